#version 430
// LMFR's internal anti-aliasing: 3 x 3 Gaussian (sigma 1) in the LP buffer, rows wrapped around the seam,
// columns clamped (renderers/antialias.py lp_filter "gaussian3"); weights from antialias._gauss1d.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lp_cols.glsl"
#include "lp_pad.glsl"
uniform vec3 u_k;

void main() {
    uint i = gid();
    if (i < uint(u_lp_w * u_lp_h)) {
        int c = int(i) % u_lp_w, j = int(i) / u_lp_w;
        vec3 acc = vec3(0.0);
        for (int dc = -1; dc <= 1; dc++)
            for (int dr = -1; dr <= 1; dr++)
                acc += u_k[dc + 1] * u_k[dr + 1] * src_at(pad_texel(c + dc, j + PAD + dr));
        put(ivec2(c, j), acc);
    }
}
