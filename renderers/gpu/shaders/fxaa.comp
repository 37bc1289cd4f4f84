// FXAA 3.11 in the LP buffer: renderers/antialias.py fxaa_pixel, generated (fxaa_gen.glsl), on the padded LP
// buffer (lp_pad.glsl). Only the rows the inverse mapping reads (j < n[c], c < w_eff) are filtered.
#include "common.glsl"
#include "lp_cols.glsl"
#include "lp_pad.glsl"

// The CPU's FXAA image (padded rows, channels r, g, b, luma) and its size, read by the generated kernel.
float aa_img(int y, int x, int ch);
int aa_dim(int k);
#include "fxaa_gen.glsl"
float aa_img(int y, int x, int ch) {
    ivec2 p = pad_texel(x, y);
    return ch == AA_LUMA_CHANNEL ? imageLoad(luma, p).x : imageLoad(src, p)[ch];
}
int aa_dim(int k) { return k == 0 ? u_lp_h + 2 * PAD : u_lp_w; }

void main() {
    uint i = gid();
    if (i < uint(u_lp_w * u_lp_h)) {
        int c = int(i) % u_lp_w, j = int(i) / u_lp_w;
        put(ivec2(c, j), (c < u_w_eff && j < col_n(c)) ? vec3(aa_fxaa_pixel(u_subpix, u_edge_threshold,
            u_edge_threshold_min, c, j + PAD)) : src_at(ivec2(c, j)));
    }
}
