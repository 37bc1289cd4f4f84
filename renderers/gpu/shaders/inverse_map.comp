// Screen image from the LP buffer: lp_inverse_pixel, generated from renderers/_lp.py inverse_pixel.
#include "common.glsl"
#include "lp_cols.glsl"
#include "lp_map.glsl"
#include "screen_out.glsl"
layout(binding = 4, rgba32f) uniform restrict readonly image2D src;
#include "lp_inverse_gen.glsl"

void main() {
    uint i = gid();
    if (i < uint(u_n)) screen_out(int(i), lp_inverse_pixel(int(i) % u_width, float(int(i) / u_width)));
}
