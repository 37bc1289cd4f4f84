// Buffers of the FPSM passes (renderers/gpu/fpsm.py; seed 003 §3.1, Eq 1-8), after lc_buffers.glsl. The FPSM
// of renderers/lightcuts/fpsm.py in float32, on the G-buffer; the resampling follows scikit-image's resize
// (scipy.ndimage.zoom, grid mode, edges replicated) to the sample position.
layout(std430, binding = 14) buffer FpPix { vec4 fp_px[]; };   // luminance of fb' upsampled | fb_st | fb_l | rho
layout(std430, binding = 15) buffer FpLow { float fp_low[]; }; // bicubic coefficients | pyramid levels 1, 2
uniform int u_width;
uniform int u_height;
uniform ivec2 u_g1;        // level 1 of the pyramid: width, height (offset u_g1_at)
uniform ivec2 u_g2;        // level 2
uniform int u_g1_at;
uniform int u_g2_at;
// Keys of the smallest and largest finite rho (Eq 8) after the G-buffer's bounds.
const int RHO_LO = 6;
const int RHO_HI = 7;

// 1-4-6-4-1 / 16 (fpsm._BINOMIAL, the 5 x 5 Gaussian of Eq 6 and of the pyramid).
float binom(int d) { return d == 0 ? 0.375 : (abs(d) == 1 ? 0.25 : 0.0625); }

// Linear interpolation of level `at` (w x h) at the centre of screen pixel (x, y) of a u_width x u_height image
// (skimage resize, order 1: x_in = (x + 0.5) w_in / w_out - 0.5, clamped to the edge pixels).
float level_at(int at, ivec2 size, int x, int y) {
    vec2 c = clamp((vec2(x, y) + 0.5) * vec2(size) / vec2(u_width, u_height) - 0.5, vec2(0.0), vec2(size - 1));
    ivec2 i0 = min(ivec2(floor(c)), max(size - 2, ivec2(0)));
    ivec2 i1 = min(i0 + 1, size - 1);
    vec2 f = c - vec2(i0);
    float a = fp_low[at + i0.y * size.x + i0.x], b = fp_low[at + i0.y * size.x + i1.x];
    float d = fp_low[at + i1.y * size.x + i0.x], e = fp_low[at + i1.y * size.x + i1.x];
    return (a * (1.0 - f.x) + b * f.x) * (1.0 - f.y) + (d * (1.0 - f.x) + e * f.x) * f.y;
}
