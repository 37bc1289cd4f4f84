// LS' of seed 003 Algorithm 2 (the generated multires.sort_pixel): each low-resolution pixel's samples with a light
// sorted by leaf offset; the count goes to pix.w.
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"

void main() {
    cnt_begin();
    int i = int(gid());
    if (i < u_n) pix[u_first + i].w = lc_sort_pixel(i);
    cnt_end();
}
