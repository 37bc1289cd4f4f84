#version 430
// One light per cut node (seed 003 Algorithm 2): the generated multires.select_pixel with MULTIRES (the reuse of
// LS' of the low-resolution pixel under this one, found in double precision as on the CPU), else
// _kernels.sample_pixel (hierarchical importance sampling alone).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"
uniform int u_width;       // of the frame
uniform dvec2 u_lr_scale;  // (w' / w, h' / h)
uniform int u_lr_width;
uniform int u_lr_height;

void main() {
    cnt_begin();
    int i = int(gid()), px = u_first + i, reused = 0;
    if (i < u_n) {
#if MULTIRES
        int qx = min(int(double(px % u_width) * u_lr_scale.x), u_lr_width - 1);
        int qy = min(int(double(px / u_width) * u_lr_scale.y), u_lr_height - 1);
        reused = lc_select_pixel(i, qy * u_lr_width + qx, u_seed);
#else
        lc_sample_pixel(i, u_seed);
#endif
        pix[px].z = reused;
        cnt_add(C_REUSED, uint(reused));
    }
    cnt_end();
}
