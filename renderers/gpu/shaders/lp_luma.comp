// FXAA's luma of every LP pixel: aa_luma, generated from renderers/antialias.py luma.
#include "common.glsl"
#include "constants_gen.glsl"
#include "luma_gen.glsl"
#include "filters_decl_gen.glsl"

void main() {
    uint i = gid();
    if (i < uint(u_n)) {
        ivec2 p = ivec2(int(i) % u_lp_w, int(i) / u_lp_w);
        vec4 c = imageLoad(src, p);
        imageStore(luma, p, vec4(aa_luma(c.x, c.y, c.z, u_exposure)));
    }
}
