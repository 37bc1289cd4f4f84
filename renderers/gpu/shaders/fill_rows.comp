// renderers/pipeline.py fill_unshaded: lp_fill_row (generated from renderers/_lp.py fill_row) on each LP row.
#include "common.glsl"
layout(binding = 4, rgba32f) uniform restrict image2D lp;
layout(std430, binding = 14) readonly buffer Flags { uint flags[]; };
uniform int u_lp_w;
#include "lp_fill_gen.glsl"

void main() {
    if (int(gid()) < u_n) lp_fill_row(int(gid()), u_lp_w);
}
