// Stochastic lightcuts on the GPU (renderers/gpu/lightcuts.py): the light tree of renderers/lightcuts/tree.py
// and, line for line in float32, the kernels of renderers/lightcuts/_kernels.py (bounds, the cut-refinement
// error, hierarchical importance sampling, the Lambertian contribution), the reuse of multires.py (seed 003
// Algorithm 2, Eq 9) and the CPU's random numbers (generated from _kernels.uniform), so that both backends draw
// the same samples up to the float32 rounding of the probabilities. Needs scene.glsl (fetch, trace).

// The tree in an RGBA32UI image (image unit 4; 6 N texels): node k (1 <= k < 2N) at texels 2k, 2k + 1:
// (bmin, intensity), (bmax, 0); leaf j (0 <= j < N) at 4N + 2j, 4N + 2j + 1: (RGB intensity, 0), (emitter
// normal, 0). A leaf's light sits at its node's box (bmin = bmax = position).
layout(binding = 4, rgba32ui) uniform restrict readonly uimage2D t_tree;
uniform int u_n_leaves;    // N
uniform int u_levels;      // log2 N + 1 (the n of seed 003 Eq 9)
uniform float u_clamp2;    // (0.001 scene light radius)^2 (sampling.clamp2)
uniform int u_one_sided;   // the tree has emitter normals

vec3 node_min(int k) { return fetchf(t_tree, 2 * k).xyz; }
vec3 node_max(int k) { return fetchf(t_tree, 2 * k + 1).xyz; }
float node_inten(int k) { return fetchf(t_tree, 2 * k).w; }
vec3 light_pos(int j) { return node_min(u_n_leaves + j); }
vec3 light_rgb(int j) { return fetchf(t_tree, 4 * u_n_leaves + 2 * j).xyz; }
vec3 light_nrm(int j) { return fetchf(t_tree, 4 * u_n_leaves + 2 * j + 1).xyz; }

// -- random numbers: _kernels.uniform, generated (lightcuts_gen.glsl): equal to the CPU's float64 value ---------
// The cut of the current shading point (lc_refine_cut, generated from _kernels.refine_cut): CUT_MAX (a define)
// node ids, sorted by heap offset (Algorithm 2 reads them in that order; the sample slots follow it).
int lc_cut[CUT_MAX];
float lc_err[CUT_MAX];
#include "lightcuts_gen.glsl"
const float LC_ONE_MINUS_F = 0.99999994;   // the largest float below 1
// The same as a float32 in [0, 1).
float lc_uniform_f(uvec2 seed, uvec2 pixel, uint slot) {
    return min(float(lc_uniform(seed, pixel, uvec2(slot, 0u))), LC_ONE_MINUS_F);
}

// -- bounds (_kernels.frame; the rest, and the cut refinement, generated) -----------------------------------------------
// Orthonormal tangents (T, B) of a unit normal (Duff et al. 2017).
void lc_frame(vec3 n, out vec3 t, out vec3 b) {
    float sgn = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + sgn * n.x * n.x * a, sgn * c, -sgn * n.x);
    b = vec3(c, sgn + n.y * n.y * a, -n.y);
}

// Generated (lightcuts_gen.glsl, float32): lc_box_terms (geometry bound, dmin^2, dmax^2 of a node's box, `precise`
// sums in the CPU's axis order so that a parent's bound is never below a leaf's cosine), lc_error_bound (the
// cut-refinement error), lc_prob_left and lc_descend (hierarchical importance sampling; float32 where the CPU has
// float64: the rescaling loses about a bit per level, so deep in the tree a decision may differ from the CPU's;
// measured on cornell_many the images are those of a float64 u).

// Node k can contribute at p (non-zero intensity and geometry bound).
bool node_live(vec3 p, vec3 n, vec3 t, vec3 b, int k) {
    return node_inten(k) > 0.0 && lc_box_terms(p, n, t, b, k).x > 0.0;
}

// The leaf node reached from `node` with uniform u; `pdf` the product of the branch probabilities.
int descend(vec3 p, vec3 n, vec3 t, vec3 b, int node, float u, out float pdf) {
    vec2 r = lc_descend(p, n, t, b, node, u);
    pdf = r.y;
    return int(r.x);
}

// -- shading (_kernels.shade_samples, sampling.shade_tile) ----------------------------------------------------
// Unshadowed Lambertian estimate of light `leaf` (a heap node) drawn with probability pdf:
// albedo/pi I_rgb cos / max(d^2, clamp2) / pdf, times the emitter cosine for one-sided lights.
vec3 light_estimate(vec3 p, vec3 n, vec3 alb, int leaf, float pdf) {
    if (leaf < 0 || pdf <= 0.0) return vec3(0.0);
    int j = leaf - u_n_leaves;
    return alb * light_rgb(j) * lc_sample_weight(p, n, j, pdf);   // generated from _kernels.sample_weight
}

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
