#version 430
// Shading of the hits (renderers/_shade.py shade_contributions): unshadowed contributions (its light_loop,
// generated), light culling, the lights still to shadow-test (masks) and the radiance of the rest (partial).
// Misses take the background.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "samples.glsl"
float lum[LIGHT_COUNT];     // the point's unshadowed light luminances and contributions (shade_light_loop)
vec3 contrib[LIGHT_COUNT];
#include "light_loop_gen.glsl"

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
        int k = floatBitsToInt(hits[i].x);
        if (k < 0) {
            partial[i] = vec4(u_background, 0.0);
            for (int w = 0; w < MASK_WORDS; w++) masks[i * uint(MASK_WORDS) + uint(w)] = 0u;
            cnt_add(C_MISSED_RAYS, 1u);
        } else {
            vec3 d = samples[i].xyz;
            Surf s = surface(k, u_origin, d, hits[i].y);
            vec2 tg = shade_light_loop(0, LIGHT_COUNT, s.p.x, s.p.y, s.p.z, s.n.x, s.n.y, s.n.z, s.v.x, s.v.y, s.v.z,
                                       s.kd, s.a.x, s.a.y, s.a.z, s.glossy ? 1.0 : 0.0, s.ks.x, s.ks.y, s.ks.z, s.norm,
                                       s.s_exp);
            float total = tg.x;
            // Culling (documented bound in _shade.py): in ascending order of contribution, the lights whose
            // running sum stays <= eps * total are dropped; light j goes iff the sum up to it (ties by index)
            // does, since the running sums only grow.
            float budget = u_light_cull * total;
            bool cull = u_light_cull > 0.0 && total > 0.0;
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
                masks[i * uint(MASK_WORDS) + uint(w)] = bits;
            }
            partial[i] = vec4(c, 0.0);
            cnt_add(C_SHADING_POINTS, 1u);
            cnt_add(C_GLOSSY_EVALUATIONS, uint(tg.y));
            cnt_add(C_LIGHTS_CULLED, culled);
            cnt_add(C_SHADOW_RAYS_SKIPPED, uint(LIGHT_COUNT) - n_cast);
        }
    }
    cnt_end();
}
