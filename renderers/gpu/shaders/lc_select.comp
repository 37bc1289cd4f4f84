// One light per cut node (seed 003 Algorithm 2): the generated multires.select_pixel with MULTIRES (the reuse of
// LS' of the low-resolution pixel under this one), else _kernels.sample_pixel (hierarchical importance sampling).
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"

void main() {
    cnt_begin();
    int i = int(gid()), px = u_first + i, reused = 0;
    if (i < u_n) {
#if MULTIRES
        reused = lc_select_pixel(i, lc_low_res_pixel(px % u_width, px / u_width), u_seed);
#else
        lc_sample_pixel(i, u_seed);
#endif
        pix[px].z = reused;
        cnt_add(C_REUSED, uint(reused));
    }
    cnt_end();
}
