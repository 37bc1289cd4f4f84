#version 430
// Project each left sample's hit point (a miss: its direction at infinity) into the right view, map it into
// the LP buffer (u by the forward mapping, phi the polar angle) and splat its depth into the LP pixel holding
// it (renderers/pipeline.py LPLayout.lp_coords).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "samples.glsl"
#include "lp_cols.glsl"
#include "lp_map.glsl"
#include "rep.glsl"
uniform vec3 u_left_pos;
uniform vec3 u_right_pos;
uniform vec3 u_right_f;
uniform vec3 u_right_r;
uniform vec3 u_right_u;
uniform float u_tan;
uniform vec2 u_screen;

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
        vec3 d = samples[i].xyz;
        int idx = floatBitsToInt(samples[i].w);
        bool hit = floatBitsToInt(hits[i].x) >= 0;
        vec3 rel = hit ? u_left_pos + d * hits[i].y - u_right_pos : d;
        float zf = dot(rel, u_right_f);
        vec4 wv = vec4(0.0, 0.0, REP_INF, intBitsToFloat(-1));
        if (zf > 0.0) {
            float sx = dot(rel, u_right_r) / zf, sy = dot(rel, u_right_u) / zf;
            float xr = (sx / u_tan + u_screen.x / u_screen.y) * u_screen.y / 2.0;
            float yr = (1.0 - sy / u_tan) * u_screen.y / 2.0;
            float dx = xr - u_gaze.x, dy = yr - u_gaze.y;
            float u = lp_u(dx, dy), phi = lp_angle(dx, dy);
            int c = clamp(int(floor(u)), 0, u_w_eff - 1);
            vec4 col = cols(c);
            int r = wrap_row(int(floor(phi * col.y)), max(int(col.z), 1));
            int lin = r * u_lp_w + c;
            float z = hit ? zf : REP_INF;
            wv = vec4(u, phi, z, intBitsToFloat(lin));
            atomicMin(zbuf[lin], floatBitsToUint(z));
            covered[lin] = 1u;
        }
        warp[idx] = wv;
    }
    cnt_end();
}
