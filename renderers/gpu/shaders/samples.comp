// The sample pipeline (renderers/gpu/frame.py SAMPLE_PASSES: renderers/pipeline.py and tracer.py cut into passes),
// one invocation per pixel or sample. PASS is one of
//   GBUFFER       deferred visibility (seed 001 §3.4) of every screen pixel centre: triangle and t
//   GEN_GT        SPP GT samples per pixel of rows [u_y0, ...) at renderers/_gt.py sample_offset, slot u_slot_base + i
//   GEN_DEFERRED  an LP sample takes the G-buffer pixel under its screen position (clamped to the display) and that
//                 pixel's camera ray (renderers/pipeline.py GBuffer.shade)
//   RESOLVE       GT pixels of rows [u_y0, ...) from the samples of rows [u_s0, u_s1): _gt.py resolve_pixel (box, tent)
// and then, over the samples (k, d, at: the hit triangle, the ray, the first mask word):
//   TRACE         primary visibility: closest hit of each sample's ray (Embree INTERSECT in tracer.py)
//   SHADE         renderers/_shade.py shade_contributions: unshadowed contributions (its light_loop), light culling,
//                 the lights still to shadow-test (masks), the radiance of the rest (partial); misses: background
//   SHADOW        shadow rays (Embree OCCLUDED): one per light still in the mask; an occluded light leaves the mask
//   GATHER        partial + the lights that passed, into the sample's output slot (_shade.py accumulate);
//                 non-finite values are counted (the host refuses them)
#include "common.glsl"
#include "scene.glsl"
#include "camera.glsl"
#include "samples.glsl"
#include "passes_decl_gen.glsl"
#if PASS == GEN_DEFERRED
#include "lp_cols.glsl"
#elif PASS == SHADE
float lum[LIGHT_COUNT];     // the point's unshadowed light luminances and contributions (shade_light_loop)
vec3 contrib[LIGHT_COUNT];
#include "light_loop_gen.glsl"
#elif PASS == GEN_GT || PASS == RESOLVE
double gt_part[8];          // resolve_pixel's running sums
#include "gt_gen.glsl"
#endif

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
#if PASS >= TRACE
        int k = floatBitsToInt(hits[i].x);
        vec3 d = samples[i].xyz;
        uint at = i * uint(MASK_WORDS);
#endif
#if PASS == GBUFFER
        float t;
        int k = trace(u_origin, camera_ray_d(dvec2(int(i) % u_width, int(i) / u_width) + 0.5LF), INF, false, t);
        gbuf[i] = vec2(intBitsToFloat(k), t);
        cnt_add(C_RAYS_PRIMARY, 1u);
#elif PASS == GEN_GT
        int pix = int(i) / SPP, s = int(i) - pix * SPP;
        int px = pix % u_width, py = u_y0 + pix / u_width;
        dvec2 xy = dvec2(px, py) + gt_sample_offset(px, py, s, SPP, SPP_SIDE);
        samples[i] = vec4(camera_ray_d(xy), intBitsToFloat(u_slot_base + int(i)));
#elif PASS == GEN_DEFERRED
        int idx = floatBitsToInt(samples[i].w);
        dvec2 xy = lp_position_d(idx % u_lp_w, idx / u_lp_w);
        ivec2 p = clamp(ivec2(floor(xy)), ivec2(0), ivec2(u_screen) - 1);
        samples[i].xyz = camera_ray_d(dvec2(p) + 0.5LF);
        hits[i] = gbuf[p.y * int(u_screen.x) + p.x];
#elif PASS == RESOLVE
        int px = int(i) % u_width, p = 3 * (u_y0 * u_width + int(i));
        dvec3 c = gt_resolve_pixel(px, u_y0 - u_s0 + int(i) / u_width, u_width, u_s1 - u_s0, SPP, u_tent);
        for (int k = 0; k < 3; k++) img[p + k] = float(c[k]);
#elif PASS == TRACE
        float t;
        k = trace(u_origin, d, INF, false, t);
        hits[i] = vec2(intBitsToFloat(k), t);
        cnt_add(C_RAYS_PRIMARY, 1u);
#elif PASS == SHADE
        if (k < 0) {
            partial[i] = vec4(u_background, 0.0);
            for (int w = 0; w < MASK_WORDS; w++) masks[at + uint(w)] = 0u;
            cnt_add(C_MISSED_RAYS, 1u);
        } else {
            Surf s = surface(k, u_origin, d, hits[i].y);
            vec2 tg = shade_light_loop(0, LIGHT_COUNT, s.p.x, s.p.y, s.p.z, s.n.x, s.n.y, s.n.z, s.v.x, s.v.y, s.v.z,
                                       s.kd, s.a.x, s.a.y, s.a.z, s.glossy ? 1.0 : 0.0, s.ks.x, s.ks.y, s.ks.z, s.norm,
                                       s.s_exp);
            // Culling (documented bound in _shade.py): in ascending order of contribution, the lights whose
            // running sum stays <= eps * total are dropped; light j goes iff the sum up to it (ties by index)
            // does, since the running sums only grow.
            float budget = u_light_cull * tg.x;
            bool cull = u_light_cull > 0.0 && tg.x > 0.0;
            uint culled = 0u, n_cast = 0u;
            vec3 c = s.base;
            for (int w = 0; w < MASK_WORDS; w++) {
                uint bits = 0u;
                for (int b = 0; b < 32; b++) {
                    int j = w * 32 + b;
                    if (j >= LIGHT_COUNT || lum[j] <= 0.0) continue;
                    if (cull) {
                        float acc = 0.0;
                        for (int q = 0; q < LIGHT_COUNT; q++)
                            if (lum[q] > 0.0 && (lum[q] < lum[j] || (lum[q] == lum[j] && q <= j))) acc += lum[q];
                        if (acc <= budget) { culled++; continue; }
                    }
                    if (light_casts(j)) {
                        bits |= 1u << uint(b);
                        n_cast++;
                    } else {
                        c += contrib[j];
                    }
                }
                masks[at + uint(w)] = bits;
            }
            partial[i] = vec4(c, 0.0);
            cnt_add(C_SHADING_POINTS, 1u);
            cnt_add(C_GLOSSY_EVALUATIONS, uint(tg.y));
            cnt_add(C_LIGHTS_CULLED, culled);
            cnt_add(C_SHADOW_RAYS_SKIPPED, uint(LIGHT_COUNT) - n_cast);
        }
#elif PASS == SHADOW
        if (k >= 0) {
            vec3 n = facing_normal(k, d), p = u_origin + d * hits[i].y;
            uint rays = 0u;
            for (int w = 0; w < MASK_WORDS; w++) {
                uint keep = masks[at + uint(w)];
                for (uint m = keep; m != 0u; m &= m - 1u) {
                    int b = findLSB(m);
                    vec3 so, sd;
                    float dist, t;
                    shadow_ray(w * 32 + b, p, n, u_offset, u_far, so, sd, dist);
                    rays++;
                    if (trace(so, sd, dist, true, t) >= 0) keep &= ~(1u << uint(b));
                }
                masks[at + uint(w)] = keep;
            }
            cnt_add(C_RAYS_SHADOW, rays);
        }
#elif PASS == GATHER
        vec3 c = partial[i].xyz;
        if (k >= 0) {
            Surf s = surface(k, u_origin, d, hits[i].y);
            for (int w = 0; w < MASK_WORDS; w++)
                for (uint m = masks[at + uint(w)]; m != 0u; m &= m - 1u)
                    c += light_contribution(s, 32 * w + findLSB(m));
        }
        if (any(isnan(c)) || any(isinf(c))) cnt_add(C_NONFINITE, 1u);
        store_out(floatBitsToInt(samples[i].w), c);
#endif
    }
    cnt_end();
}
