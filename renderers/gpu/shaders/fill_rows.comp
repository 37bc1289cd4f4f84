// renderers/pipeline.py fill_unshaded: lp_fill_row (generated from renderers/_lp.py fill_row) on each LP row.
#include "common.glsl"
#include "filters_decl_gen.glsl"
#include "flags_decl_gen.glsl"
#include "lp_fill_gen.glsl"

void main() {
    if (int(gid()) < u_n) lp_fill_row(int(gid()), u_lp_w);
}
