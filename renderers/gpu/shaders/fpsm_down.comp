#version 430
// One level of the Burt-Adelson pyramid (fpsm.laplacian_pyramid): the 5 x 5 binomial blur of the level below
// (edges replicated) at its even pixels. LEVEL 1 reads the upsampled luminance, LEVEL 2 level 1.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lc_buffers.glsl"
#include "fpsm.glsl"

void main() {
    cnt_begin();
    uint i = gid();
#if LEVEL == 1
    ivec2 src = ivec2(u_width, u_height), dst = u_g1;
    int out_at = u_g1_at;
#else
    ivec2 src = u_g1, dst = u_g2;
    int out_at = u_g2_at;
#endif
    if (i < uint(u_n)) {
        int x = 2 * (int(i) % dst.x), y = 2 * (int(i) / dst.x);
        float v = 0.0;
        for (int dy = -2; dy <= 2; dy++) {
            int yy = clamp(y + dy, 0, src.y - 1);
            for (int dx = -2; dx <= 2; dx++) {
                int k = yy * src.x + clamp(x + dx, 0, src.x - 1);
#if LEVEL == 1
                float s = fp_px[k].x;
#else
                float s = fp_low[u_g1_at + k];
#endif
                v += binom(dy) * binom(dx) * s;
            }
        }
        fp_low[out_at + int(i)] = v;
    }
    cnt_end();
}
