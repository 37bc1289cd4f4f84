// The LP buffer as renderers/antialias.py lp_filter sees it: rows continued around the angular seam by PAD
// rows on each side (renderers/_lp.py wrap_pad: padded row y of column c is LP row (y - PAD) mod n[c]), and
// clamped at the padded buffer's edges like the CPU filters' edge handling.
#include "filters_decl_gen.glsl"

// LP texel of padded row y (clamped to [0, h + 2 PAD)), column c (clamped to [0, w)).
ivec2 pad_texel(int c, int y) {
    c = clamp(c, 0, u_lp_w - 1);
    y = clamp(y, 0, u_lp_h + 2 * PAD - 1);
    return ivec2(c, wrap_row(y - PAD, max(col_n(c), 1)));
}
vec3 src_at(ivec2 p) { return imageLoad(src, p).xyz; }
void put(ivec2 p, vec3 c) { imageStore(dst, p, vec4(c, 0.0)); }
