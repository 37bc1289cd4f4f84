// The forward mapping (screen -> LP column u) of the method METHOD: lp_table_u, generated from renderers/_lp.py
// (the CPU's u(r) table, USE_TABLE, else the kernel fov_point with the CPU's parameter vector P = FP).
#include "lp_map_decl_gen.glsl"
#include "foveation_gen.glsl"
#if USE_TABLE
#define lp_utab(k) utab[k].x
#define lp_exact(k) int(utab[k].y)
#else
#define lp_utab(k) 0.0
#define lp_exact(k) 1
#endif
#include "lp_u_gen.glsl"
float lp_u(float dx, float dy) { return lp_table_u(dx, dy); }

// Polar angle in [0, 2 pi) (seed 001 Eq 1's indicator): the CPU's kernel, renderers/foveation/_kernels.py angle.
float lp_angle(float dx, float dy) { return fov_angle(dx, dy); }
