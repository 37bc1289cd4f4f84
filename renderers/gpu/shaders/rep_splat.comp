// The splats' colours: each left sample whose depth is the minimum at its target LP pixel writes its colour
// there, unless a warped triangle was nearer by the margin. PHASE 1 claims the pixel (rep.glsl winner: the
// largest sample index among equal depths), PHASE 2 writes the winner's colour.
#include "common.glsl"
#include "rep.glsl"

void main() {
    uint idx = gid();
    if (idx < uint(u_lp_w * u_lp_h) && (flags[idx] & 1u) != 0u) {
        vec4 wv = warp[idx];
        int lin = floatBitsToInt(wv.w);
        if (lin >= 0 && floatBitsToUint(wv.z) == zbuf[lin] && ztri[lin] == floatBitsToUint(REP_INF)) {
#if PHASE == 1
            atomicMax(winner[lin], idx + 1u);
#else
            if (winner[lin] == idx + 1u)
                imageStore(right_lp, ivec2(lin % u_lp_w, lin / u_lp_w),
                           imageLoad(left_lp, ivec2(int(idx) % u_lp_w, int(idx) / u_lp_w)));
#endif
        }
    }
}
