// The LP buffer's columns (renderers/pipeline.py LPLayout): per column c the screen distance of its centre
// from the gaze r(c + 0.5) (the mapping's inverse, evaluated by the CPU code), L[c] / 2 pi, the row count n[c]
// and the angular period L[c] (seed 001 Eq 8-9: row j is the angle 2 pi (j + 0.5) / L[c]).
layout(binding = 7, rgba32f) uniform restrict readonly image2D t_cols;   // TEX_WIDTH columns per row
#define cols(c) imageLoad(t_cols, ivec2((c) % TEX_WIDTH, (c) / TEX_WIDTH))
uniform vec2 u_gaze;
uniform int u_lp_w;
uniform int u_lp_h;
uniform int u_w_eff;

int col_n(int c) { return int(cols(c).z); }

// (cos, sin) of each LP pixel's polar angle 2 pi (j + 0.5) / L[c], computed by the CPU in float64 (exact zeros
// on the axes, where float32 sin(pi) is not).
layout(binding = 6, rg32f) uniform restrict readonly image2D t_dirs;

// Screen position of the centre of LP pixel (column i, row j): the inverse mapping (seed 001 Eq 10-11).
vec2 lp_position(int i, int j) {
    return u_gaze + cols(i).x * imageLoad(t_dirs, ivec2(i, j)).xy;
}

// Row r modulo n for any integer r >= -n * 64 (GLSL's % is undefined for negative operands).
int wrap_row(int r, int n) {
    if (r >= 0 && r < n) return r;   // the common case, without an integer division
    if (r < 0) r += n * ((-r + n - 1) / n);
    return r % n;
}
