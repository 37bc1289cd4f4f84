#version 430
// Screen image from the LP buffer: bilinear across the two columns around u - 0.5 and, in each, the two rows
// around theta L[c] / 2 pi - 0.5, rows wrapping at the seam (renderers/_lp.py inverse_map_table).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lp_cols.glsl"
#include "lp_map.glsl"
#include "screen_out.glsl"
layout(binding = 4, rgba32f) uniform restrict readonly image2D src;

vec3 lp_at(int row, int col) { return imageLoad(src, ivec2(col, row)).xyz; }

// _lp._rows_fast: the rows around t (>= -0.5) wrapped modulo n, and the weight of the second.
void rows_around(float t, int n, out int r0, out int r1, out float f) {
    if (t < 0.0) { r0 = n - 1; r1 = 0; f = t + 1.0; return; }
    r0 = int(t);
    f = t - float(r0);
    if (r0 >= n - 1) { r0 = r0 % n; r1 = (r0 + 1) % n; }
    else r1 = r0 + 1;
}

void main() {
    uint i = gid();
    if (i < uint(u_n)) {
        float dx = float(int(i) % u_width) + 0.5 - u_gaze.x;
        float dy = float(int(i) / u_width) + 0.5 - u_gaze.y;
        float u = lp_u(dx, dy);
        float theta = lp_angle(dx, dy);
        float uc = clamp(u - 0.5, 0.0, float(u_w_eff) - 1.0);
        int c0 = int(uc);
        float fu = uc - float(c0);
        int c1 = min(c0 + 1, u_w_eff - 1);
        int a0, a1, b0, b1;
        float fa, fb;
        vec4 k0 = cols(c0), k1 = cols(c1);
        rows_around(theta * k0.y - 0.5, max(int(k0.z), 1), a0, a1, fa);
        rows_around(theta * k1.y - 0.5, max(int(k1.z), 1), b0, b1, fb);
        vec3 c = (1.0 - fu) * (1.0 - fa) * lp_at(a0, c0) + (1.0 - fu) * fa * lp_at(a1, c0)
            + fu * (1.0 - fb) * lp_at(b0, c1) + fu * fb * lp_at(b1, c1);
        screen_out(int(i), c);
    }
}
