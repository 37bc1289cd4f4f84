#version 430
// Forward grid warping in the LP buffer (Wissmann et al. 2020; renderers/_lp.py grid_warp / _raster_triangle):
// each quad of neighbouring left samples without a depth discontinuity is split into two triangles, warped to
// the right view's LP coordinates and rasterised at the LP pixel centres. PHASE 1 takes the depth minimum of
// the triangles nearer than the splats by the margin (atomicMin); PHASE 2 claims the pixel for the triangle of
// largest id among those whose depth is that minimum (rep.glsl winner), PHASE 3 writes that triangle's colour.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lp_cols.glsl"
#include "rep.glsl"
layout(binding = 5, rgba32f) uniform restrict readonly image2D left_lp;
layout(binding = 4, rgba32f) uniform restrict writeonly image2D right_lp;
uniform float u_max_ratio;
uniform float u_max_extent;

void raster(int ka, int kb, int kc, uint tri) {
    vec4 A = warp[ka], B = warp[kb], Cc = warp[kc];
    vec3 pu = vec3(A.x, B.x, Cc.x), pp = vec3(A.y, B.y, Cc.y), pz = vec3(A.z, B.z, Cc.z);
    if (max(max(pp.x, pp.y), pp.z) - min(min(pp.x, pp.y), pp.z) > 3.141592653589793)  // straddles the seam
        pp += mix(vec3(0.0), vec3(6.283185307179586), lessThan(pp, vec3(3.141592653589793)));
    float umin = min(min(pu.x, pu.y), pu.z), umax = max(max(pu.x, pu.y), pu.z);
    if (umax - umin > u_max_extent) return;
    int c0 = max(0, int(ceil(umin - 0.5))), c1 = min(u_w_eff - 1, int(floor(umax - 0.5)));
    float det = (pu.y - pu.x) * (pp.z - pp.x) - (pu.z - pu.x) * (pp.y - pp.x);
    if (abs(det) < 1e-18) return;
    float pmin = min(min(pp.x, pp.y), pp.z), pmax = max(max(pp.x, pp.y), pp.z);
#if PHASE == 3
    ivec2 ta = ivec2(ka % u_lp_w, ka / u_lp_w), tb = ivec2(kb % u_lp_w, kb / u_lp_w);
    ivec2 tc = ivec2(kc % u_lp_w, kc / u_lp_w);
    vec3 ca = imageLoad(left_lp, ta).xyz, cb = imageLoad(left_lp, tb).xyz, cc = imageLoad(left_lp, tc).xyz;
#endif
    for (int c = c0; c <= c1; c++) {
        vec4 col = cols(c);
        int n = int(col.z);
        if (n <= 0) continue;
        float per = col.y;
        if ((pmax - pmin) * per > u_max_extent) continue;
        float uc = float(c) + 0.5;
        int j0 = int(ceil(pmin * per - 0.5)), j1 = int(floor(pmax * per - 0.5));
        for (int j = j0; j <= j1; j++) {
            float pc = (float(j) + 0.5) / per;
            float b1 = ((uc - pu.x) * (pp.z - pp.x) - (pu.z - pu.x) * (pc - pp.x)) / det;
            float b2 = ((pu.y - pu.x) * (pc - pp.x) - (uc - pu.x) * (pp.y - pp.x)) / det;
            float b0 = 1.0 - b1 - b2;
            if (b0 < -1e-9 || b1 < -1e-9 || b2 < -1e-9) continue;
            int idx = wrap_row(j, n) * u_lp_w + c;
            float z = b0 * pz.x + b1 * pz.y + b2 * pz.z;
#if PHASE == 1
            covered[idx] = 1u;
            if (z < uintBitsToFloat(zbuf[idx]) * (1.0 - u_splat_margin)) atomicMin(ztri[idx], floatBitsToUint(z));
#elif PHASE == 2
            if (floatBitsToUint(z) == ztri[idx]) atomicMax(winner[idx], tri + 1u);
#else
            if (floatBitsToUint(z) == ztri[idx] && winner[idx] == tri + 1u)
                imageStore(right_lp, ivec2(c, idx / u_lp_w), vec4(b0 * ca + b1 * cb + b2 * cc, 0.0));
#endif
        }
    }
}

void main() {
    uint q = gid();
    if (q < uint((u_w_eff - 1) * (u_lp_h - 1))) {
        int c = int(q) % (u_w_eff - 1), j = int(q) / (u_w_eff - 1);
        int a = j * u_lp_w + c, b = a + 1, cc = a + u_lp_w, d = cc + 1;
        if ((flags[a] & flags[b] & flags[cc] & flags[d] & 1u) == 0u) return;
        float za = warp[a].z, zb = warp[b].z, zc = warp[cc].z, zd = warp[d].z;
        float zmin = min(min(za, zb), min(zc, zd)), zmax = max(max(za, zb), max(zc, zd));
        if (!(zmax < REP_INF) || zmin <= 0.0 || zmax > zmin * u_max_ratio) return;
        raster(a, b, d, 2u * q);
        raster(a, d, cc, 2u * q + 1u);
    }
}
