#version 430
// The map (Eq 8: 1 - (rho - rho_min) / (rho_max - rho_min) over the finite rho, +inf -> 0, 1 where rho_max =
// rho_min; the retained map as stored; AFSM: fb_st) and from it each pixel's controls (ctl): the cut budget
// #L = max(1, ceil(map MAX_lspp)) on valid pixels (fpsm.light_budget), the glossy rays ceil(map MAX_rspp)
// (at least 1 with AFSM: light_budget; plugin.glossy_budget for fsl) and the map.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lc_buffers.glsl"
#include "fpsm.glsl"
uniform int u_max_lspp;
uniform int u_max_rspp;

int budget(float map, int most, int least) {
    return max(least, int(ceil(double(map) * double(most) - 1e-9LF)));
}

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
#if READING == 3
        float map = fp_px[i].y;
#elif READING == 2
        float map = fp_px[i].w;
#else
        float rho = fp_px[i].w, lo = key_float(bounds[RHO_LO]), hi = key_float(bounds[RHO_HI]);
        float map = 0.0;
        if (!isinf(rho)) map = hi > lo ? clamp(1.0 - (rho - lo) / (hi - lo), 0.0, 1.0) : 1.0;
#endif
        int rays = budget(map, u_max_rspp, READING == 3 ? 1 : 0);
        ctl[i] = ivec4(g_pos[i].w > 0.0 ? budget(map, u_max_lspp, 1) : 0, rays, floatBitsToInt(map), 0);
    }
    cnt_end();
}
