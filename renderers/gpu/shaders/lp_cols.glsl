// The LP buffer's columns (renderers/pipeline.py LPLayout): per column c the screen distance of its centre
// from the gaze r(c + 0.5) (the mapping's inverse, evaluated by the CPU code), L[c] / 2 pi, the row count n[c]
// and the angular period L[c] (seed 001 Eq 8-9: row j is the angle 2 pi (j + 0.5) / L[c]).
#include "lp_decl_gen.glsl"
#define cols(c) imageLoad(t_cols, ivec2((c) % TEX_WIDTH, (c) / TEX_WIDTH))

int col_n(int c) { return int(cols(c).z); }

// Screen position of the centre of LP pixel (column i, row j): the inverse mapping (seed 001 Eq 10-11),
// computed exactly as the CPU does, in float64: offset from the gaze = scale[i] * t_offs[i, j], where the CPU
// kernels give t_offs (VaFR: the offset itself, scale 1; LMFR/LaFR: the row's (cos, sin), scale r(i + 0.5)),
// then the gaze is added. Only then is it rounded to float32, so that the display test agrees with the CPU's to
// the last bit (a float32 position is 1e-4 px off at 2000 px: enough to flip a pixel at the display's edge).

dvec2 lp_position_d(int i, int j) {
    uvec4 q = imageLoad(t_offs, ivec2(i, j));
    precise dvec2 off = col_scale[i] * dvec2(packDouble2x32(q.xy), packDouble2x32(q.zw));
    precise dvec2 p = off + u_gaze_d;
    return p;
}
vec2 lp_position(int i, int j) { return vec2(lp_position_d(i, j)); }

// Row r modulo n for any integer r >= -n * 64 (GLSL's % is undefined for negative operands).
int wrap_row(int r, int n) {
    if (r >= 0 && r < n) return r;   // the common case, without an integer division
    if (r < 0) r += n * ((-r + n - 1) / n);
    return r % n;
}
