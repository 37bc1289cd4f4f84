// The uploaded scene (renderers/gpu/upload.py): BVH nodes and triangles (renderers/gpu/bvh.py),
// materials and lights packed like renderers/tracer.py, and the ray-triangle and BVH traversal code.
#include "constants_gen.glsl"
#include "shade_gen.glsl"

// Scene tables live in RGBA32UI images, TEX_WIDTH texels per row, read with imageLoad: on llvmpipe that is
// ~10x faster than a storage-buffer load (and ~2x a texelFetch). Floats are stored as their bits (no
// denormal flushing of the integer fields). Image units 0-3; LP passes use 4-6 (8 is OpenGL 4.3's minimum).
#include "scene_decl_gen.glsl"
#define fetch(t, k) imageLoad(t, ivec2((k) % TEX_WIDTH, (k) / TEX_WIDTH))
#define fetchf(t, k) uintBitsToFloat(fetch(t, k))

const float INF = 1.0 / 0.0;
#define BVH_STACK 66

// Möller-Trumbore with exact barycentric bounds: on the scenes' 1.4 M test rays it agrees with Embree on every
// hit and miss (a 1e-6 widening against cracks along shared edges made silhouettes catch rays Embree misses).
float hit_triangle(int k, vec3 o, vec3 d, float tmax) {
    vec3 v0 = fetchf(t_tris, 3 * k).xyz, e1 = fetchf(t_tris, 3 * k + 1).xyz, e2 = fetchf(t_tris, 3 * k + 2).xyz;
    vec3 p = cross(d, e2);
    float det = dot(e1, p);
    if (det == 0.0) return INF;
    float inv = 1.0 / det;
    vec3 s = o - v0;
    float u = dot(s, p) * inv;
    if (u < 0.0 || u > 1.0) return INF;
    vec3 q = cross(s, e1);
    float v = dot(d, q) * inv;
    if (v < 0.0 || u + v > 1.0) return INF;
    float t = dot(e2, q) * inv;
    return (t > 0.0 && t < tmax) ? t : INF;
}

// Entry distance of the ray into a box, INF if it misses before tmax. The exit distance is widened by a few
// ulps (Ize 2013) so that rounding does not cull a box whose face a hit lies on.
float hit_box(vec3 lo, vec3 hi, vec3 o, vec3 inv, float tmax) {
    vec3 t0 = (lo - o) * inv, t1 = (hi - o) * inv;
    vec3 tn = min(t0, t1), tf = max(t0, t1);
    float a = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float b = min(min(tf.x, tf.y), tf.z) * 1.0000004;
    return (a <= b && a < tmax) ? a : INF;
}

// Closest hit (any_hit false) or any hit (shadow rays) along o + t d, 0 < t < tmax: the triangle index in
// BVH order (-1 on a miss) and t. Nodes hold their children's boxes (bvh.py): a visit tests both boxes,
// intersects leaf children at once and descends into the nearer inner child, the farther one stacked.
void leaf(int first, int count, vec3 o, vec3 d, inout float best, inout int best_tri) {
    for (int k = first; k < first + count; k++) {
        float t = hit_triangle(k, o, d, best);
        if (t < best) { best = t; best_tri = k; }
    }
}

int trace(vec3 o, vec3 d, float tmax, bool any_hit, out float t_hit) {
    vec3 dd = mix(d, sign(d) * 1e-30 + d, lessThan(abs(d), vec3(1e-30)));
    dd = mix(dd, vec3(1e-30), equal(dd, vec3(0.0)));
    vec3 inv = 1.0 / dd;
    int stack[BVH_STACK];
    float stack_t[BVH_STACK];
    int sp = 0;
    int node = 0;
    int best_tri = -1;
    float best = tmax;
    while (node >= 0) {
        uvec4 l0 = fetch(t_nodes, 4 * node), l1 = fetch(t_nodes, 4 * node + 1);
        uvec4 r0 = fetch(t_nodes, 4 * node + 2), r1 = fetch(t_nodes, 4 * node + 3);
        float tl = hit_box(uintBitsToFloat(l0.xyz), uintBitsToFloat(l1.xyz), o, inv, best);
        float tr = hit_box(uintBitsToFloat(r0.xyz), uintBitsToFloat(r1.xyz), o, inv, best);
        if (tl < INF && l1.w > 0u) { leaf(int(l0.w), int(l1.w), o, d, best, best_tri); tl = INF; }
        if (tr < INF && r1.w > 0u) { leaf(int(r0.w), int(r1.w), o, d, best, best_tri); tr = INF; }
        if (any_hit && best_tri >= 0) break;
        bool hl = tl < best, hr = tr < best;
        if (hl && hr) {
            bool left_first = tl <= tr;
            stack[sp] = int(left_first ? r0.w : l0.w);
            stack_t[sp] = left_first ? tr : tl;
            sp++;
            node = int(left_first ? l0.w : r0.w);
        } else if (hl) {
            node = int(l0.w);
        } else if (hr) {
            node = int(r0.w);
        } else {
            node = -1;
            while (sp > 0) {
                sp--;
                if (stack_t[sp] < best) { node = stack[sp]; break; }
            }
        }
    }
    t_hit = best;
    return best_tri;
}

// -- shading: the data plumbing around the kernels generated from renderers/_shade.py (shade_gen.glsl) --------

struct Surf {
    vec3 p, n, v, a, ks, base;
    float kd, s_exp, norm;
    bool glossy;
};
// Column c of the CPU's material table mat_f (renderers/tracer.py pack_scene; then the texture kind, column 14).
#define material(m, c) fetchf(t_mats, 4 * (m) + (c) / 4)[(c) % 4]
Surf hit_surf;   // the record surface() fills: shade_hit_surface reads its p, n, writes a, ks, base, s_exp
#include "lights_gen.glsl"

// Unit geometric normal of triangle k facing the ray direction d.
vec3 facing_normal(int k, vec3 d) {
    vec3 e1 = fetchf(t_tris, 3 * k + 1).xyz, e2 = fetchf(t_tris, 3 * k + 2).xyz;
    return shade_facing_normal(e1.x, e1.y, e1.z, e2.x, e2.y, e2.z, d.x, d.y, d.z);
}

// Hit point, normal facing the ray and material of triangle k hit at o + t d (_shade.hit_geometry and
// _shade.hit_surface; the albedo is 0 on metallic materials, ks 0 on diffuse ones).
Surf surface(int k, vec3 o, vec3 d, float t) {
    hit_surf.p = o + d * t;
    hit_surf.n = facing_normal(k, d);
    hit_surf.v = -d;
    int m = int(fetch(t_tris, 3 * k + 1).w);
    hit_surf.glossy = shade_hit_surface(0, m);   // a, ks, base, s_exp
    vec4 lobes = shade_material_lobes(material(m, 12), material(m, 13), hit_surf.s_exp);   // kd, -, -, norm
    hit_surf.kd = lobes.x;
    hit_surf.norm = lobes.w;
    return hit_surf;
}

// Unshadowed contribution of light j (_shade.light_term, generated: lights_gen.glsl).
vec3 light_contribution(Surf s, int j) {
    return shade_light_term(j, s.p.x, s.p.y, s.p.z, s.n.x, s.n.y, s.n.z, s.v.x, s.v.y, s.v.z, s.kd, s.a.x, s.a.y,
                            s.a.z, s.glossy ? 1.0 : 0.0, s.ks.x, s.ks.y, s.ks.z, s.norm, s.s_exp).xyz;
}

bool light_casts(int j) { return fetchf(t_lights, 3 * j + 1).w > 0.5; }

// Shadow ray towards light j from p (normal n): origin offset along n, stops `offset` short of the light
// (_shade.shadow_rays; the direction and length generated from _shade.shadow_direction).
void shadow_ray(int j, vec3 p, vec3 n, float offset, float far, out vec3 o, out vec3 d, out float dist) {
    o = p + offset * n;
    vec4 r = shade_shadow_direction(j, o.x, o.y, o.z, offset, far);
    d = r.xyz;
    dist = r.w;
}
