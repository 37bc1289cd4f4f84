// LMFR's internal anti-aliasing (renderers/antialias.py lp_filter "gaussian3"): aa_gauss_pixel, generated from
// antialias.gauss_pixel, over the LP buffer padded around the seam (lp_pad.glsl); u_w: antialias._gauss1d.
#include "common.glsl"
#include "constants_gen.glsl"
#include "lp_cols.glsl"
#include "lp_pad.glsl"
#define px_at(y, x) imageLoad(src, pad_texel(x, y))
#include "gauss_gen.glsl"

void main() {
    uint i = gid();
    if (i < uint(u_lp_w * u_lp_h)) {
        int c = int(i) % u_lp_w, y = int(i) / u_lp_w + PAD, h = u_lp_h + 2 * PAD;
        put(ivec2(c, y - PAD), vec3(aa_gauss_pixel(y, c, 0, 0, LP_GAUSS_RADIUS, h, u_lp_w),
            aa_gauss_pixel(y, c, 1, 0, LP_GAUSS_RADIUS, h, u_lp_w),
            aa_gauss_pixel(y, c, 2, 0, LP_GAUSS_RADIUS, h, u_lp_w)));
    }
}
