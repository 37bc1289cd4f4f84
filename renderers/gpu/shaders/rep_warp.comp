// Forward grid warping in the LP buffer (Wissmann et al. 2020): renderers/_warp.py warp_quad, generated
// (warp_gen.glsl). Each quad of neighbouring left samples without a depth discontinuity is split into two
// triangles, rasterised at the LP pixel centres in the right view's LP coordinates. The fragments are the GPU's
// own (the CPU depth-tests in order, here threads race): PHASE 1 takes the depth minimum of the triangles nearer
// than the splats by the margin (atomicMin), PHASE 2 claims the pixel for the triangle of largest id among those
// whose depth is that minimum (rep.glsl winner), PHASE 3 writes that triangle's colour.
#include "common.glsl"
#include "lp_cols.glsl"
#include "rep.glsl"

vec3 left_col(int k) { return imageLoad(left_lp, ivec2(k % u_lp_w, k / u_lp_w)).xyz; }

// Fragment of the triangle of left samples (ka, kb, kc); its id: 2 ka (ka the quad's first sample) + which half.
void rep_fragment(int idx, float z, float b0, float b1, float b2, int ka, int kb, int kc) {
    uint tri = 2u * uint(ka) + (kb == ka + 1 ? 0u : 1u);
#if PHASE == 1
    covered[idx] = 1u;
    if (z < uintBitsToFloat(zbuf[idx]) * (1.0 - u_splat_margin)) atomicMin(ztri[idx], floatBitsToUint(z));
#elif PHASE == 2
    if (floatBitsToUint(z) == ztri[idx]) atomicMax(winner[idx], tri + 1u);
#else
    if (floatBitsToUint(z) == ztri[idx] && winner[idx] == tri + 1u)
        imageStore(right_lp, ivec2(idx % u_lp_w, idx / u_lp_w),
                   vec4(b0 * left_col(ka) + b1 * left_col(kb) + b2 * left_col(kc), 0.0));
#endif
}
#include "warp_gen.glsl"

void main() {
    uint q = gid();
    if (q < uint((u_w_eff - 1) * (u_lp_h - 1))) {
        int c = int(q) % (u_w_eff - 1), j = int(q) / (u_w_eff - 1);
        int a = j * u_lp_w + c, b = a + 1, cc = a + u_lp_w, d = cc + 1;
        if ((flags[a] & flags[b] & flags[cc] & flags[d] & 1u) != 0u)
            rep_warp_quad(a, b, cc, d, u_w_eff, u_lp_w, u_max_ratio, u_max_extent);
    }
}
