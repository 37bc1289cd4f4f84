// Cuts (seed 003 §3.1 "refine the lightcuts until the number of nodes becomes #L"): the generated
// _kernels.cut_pixel for each pixel of the tile (lc_cut), its nodes copied to the tile's sample list.
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"

void main() {
    cnt_begin();
    int i = int(gid()), m = i < u_n ? lc_cut_pixel(i) : 0;
    for (int s = 0; s < m; s++) smp[i * CUT_MAX + s].node = lc_cut[s];
    if (i < u_n) pix[u_first + i].x = m;
    cnt_end();
}
