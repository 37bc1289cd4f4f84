#version 430
// Shadow rays (Embree OCCLUDED in renderers/tracer.py): one per light still in the sample's mask; an occluded
// light leaves the mask.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "samples.glsl"
uniform float u_offset;
uniform float u_far;

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
        int k = floatBitsToInt(hits[i].x);
        if (k >= 0) {
            vec3 d = samples[i].xyz;
            vec3 n = facing_normal(k, d);
            vec3 p = u_origin + d * hits[i].y;
            uint rays = 0u;
            for (int w = 0; w < MASK_WORDS; w++) {
                uint m = masks[i * uint(MASK_WORDS) + uint(w)];
                uint keep = m;
                while (m != 0u) {
                    int b = findLSB(m);
                    m &= m - 1u;
                    vec3 so, sd;
                    float dist, t;
                    shadow_ray(w * 32 + b, p, n, u_offset, u_far, so, sd, dist);
                    rays++;
                    if (trace(so, sd, dist, true, t) >= 0) keep &= ~(1u << uint(b));
                }
                masks[i * uint(MASK_WORDS) + uint(w)] = keep;
            }
            cnt_add(C_RAYS_SHADOW, rays);
        }
    }
    cnt_end();
}
