#version 430
// Cuts (seed 003 §3.1 "refine the lightcuts until the number of nodes becomes #L"; _kernels.build_cuts): each
// valid pixel of the tile refines its cut from the root to its budget, u_budget for all (>= 0) or its own ctl.x.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"
uniform int u_budget;

void main() {
    cnt_begin();
    int i = int(gid()), px = u_first + i, m = 0;
    if (i < u_n && g_pos[px].w > 0.0) {
        vec3 p = g_pos[px].xyz, n = g_nrm[px].xyz, t, b;
        lc_frame(n, t, b);
        m = lc_refine_cut(p, n, t, b, u_budget >= 0 ? u_budget : ctl[px].x);
        for (int s = 0; s < m; s++) smp[i * CUT_MAX + s].node = lc_cut[s];
    }
    if (i < u_n) pix[px].x = m;
    cnt_end();
}
