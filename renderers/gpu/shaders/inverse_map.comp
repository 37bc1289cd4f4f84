// Screen image from the LP buffer: lp_inverse_pixel, generated from renderers/_lp.py inverse_pixel.
#include "common.glsl"
#include "lp_cols.glsl"
#include "lp_map.glsl"
#include "screen_out.glsl"
#include "filters_decl_gen.glsl"
#include "lp_inverse_gen.glsl"

void main() {
    uint i = gid();
    if (i < uint(u_n)) screen_out(int(i), lp_inverse_pixel(int(i) % u_width, float(int(i) / u_width)));
}
