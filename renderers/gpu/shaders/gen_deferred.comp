#version 430
// Deferred pipeline: each LP sample takes the G-buffer pixel under its screen position (clamped to the
// display) and that pixel's camera ray (renderers/pipeline.py GBuffer.shade).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "camera.glsl"
#include "samples.glsl"
#include "lp_cols.glsl"
layout(std430, binding = 15) readonly buffer GBuf { vec2 gbuf[]; };

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
        int idx = floatBitsToInt(samples[i].w);
        dvec2 xy = lp_position_d(idx % u_lp_w, idx / u_lp_w);
        ivec2 p = clamp(ivec2(floor(xy)), ivec2(0), ivec2(u_screen) - 1);
        samples[i].xyz = camera_ray_d(dvec2(p) + 0.5LF);
        hits[i] = gbuf[p.y * int(u_screen.x) + p.x];
    }
    cnt_end();
}
