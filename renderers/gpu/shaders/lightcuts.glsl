// Stochastic lightcuts on the GPU (renderers/gpu/lightcuts.py): the light tree of renderers/lightcuts/tree.py in an
// image (lc_tree_gen.glsl, from TREE_TEXELS there) and the kernels generated from renderers/lightcuts/_kernels.py
// and multires.py (lightcuts_gen.glsl), with the CPU's random numbers. Needs scene.glsl (fetchf, trace).
#include "lc_buffers.glsl"
#include "lc_tree_gen.glsl"

// lc_refine_cut's cut (CUT_MAX node ids, sorted by heap offset) and scratch.
int lc_cut[CUT_MAX];
float lc_err[CUT_MAX];
#include "lightcuts_gen.glsl"

// Shadow segment of visibility.EmbreeOccluder: from p offset along n towards the light, shortened to (1 - 1e-3)
// of its length, any hit.
bool occluded(vec3 p, vec3 n, int leaf, float offset) {
    vec3 o = p + offset * n;
    float t;
    return trace(o, light_pos(leaf - u_n_leaves) - o, LC_SHADOW_END, true, t) >= 0;
}

// Shadow-ray origin offset (sampling.ray_offset_for): 1e-4 of the half diagonal of the lights' box and the
// G-buffer's points (`lo`, `hi`).
float ray_offset(vec3 lo, vec3 hi) {
    vec3 a = min(node_min(1), lo), c = max(node_max(1), hi);
    return LC_OFFSET_FRACTION * max(0.5 * length(c - a), 1e-9);
}
