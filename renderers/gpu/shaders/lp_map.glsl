// The forward mapping (screen -> LP column u) of the method METHOD: the CPU's u(r) table (USE_TABLE; linear
// interpolation, exact kernel in the flagged intervals, as renderers/_lp.py inverse_map_table) or the kernel
// itself, generated from renderers/foveation/_kernels.py with the CPU's parameter vector P (FP).
layout(std430, binding = 11) readonly buffer FovParams { float FP[]; };
#include "foveation_gen.glsl"
#if USE_TABLE
layout(std430, binding = 13) readonly buffer UTab { vec2 utab[]; };   // u(k / step), exact-kernel flag
uniform float u_inv_step;
uniform int u_kmax;
#endif

float lp_u(float dx, float dy) {
#if USE_TABLE
    float s = sqrt(dx * dx + dy * dy) * u_inv_step;
    int k = min(int(s), u_kmax);
    if (s < float(u_kmax + 1) && utab[k].y == 0.0) {
        float f = s - float(k);
        return utab[k].x * (1.0 - f) + utab[k + 1].x * f;
    }
#endif
    return fov_point(METHOD, FOV_FORWARD, dx, dy).x;
}

// Polar angle in [0, 2 pi) (seed 001 Eq 1's indicator).
float lp_angle(float dx, float dy) {
    float a = fov_atan2(dy, dx);
    if (a < 0.0) a += 6.283185307179586;
    return a >= 6.283185307179586 ? 0.0 : a;
}
