// The one-bounce glossy pass (seed 003 Algorithm 1 lines 16-17, FoveatedPT; renderers/lightcuts/glossy.py):
// for every glossy pixel its rays of slots [u_r0, u_r1) (of u_rspp, or ctl.y per pixel), each a Blinn-Phong
// half-vector sample weighted k_s (s + 8)(n.w_i)(v.h) / ((s + 1) count) (glossy.lobe_ray, generated:
// glossy_gen.glsl), traced to its first hit and shaded there with emission + ambient + stochastic lightcuts of
// u_bounce_lspp nodes (CUT_MAX) with shadow rays (the hit's own gloss is not followed). Rays below the surface or
// of zero weight are not traced. Random numbers: slots 2^24 + 2r, 2^24 + 2r + 1 of the pixel for the lobe; the
// bounce's lightcuts use stream u_bounce_seed and pixel id (pixel << 20) + r, as on the CPU.
#include "common.glsl"
#include "scene.glsl"
#include "camera.glsl"
#include "lightcuts.glsl"
#include "lc_buffers.glsl"
#include "glossy_gen.glsl"

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        int px = u_first + int(i);
        bool glossy = g_pos[px].w > 0.0 && g_nrm[px].w > 0.0;
        int c = glossy ? (u_rspp >= 0 ? u_rspp : ctl[px].y) : 0;
        vec3 acc = u_r0 == 0 ? vec3(0.0) : gloss[px].xyz;
        uint live = 0u, missed = 0u;
        if (c > u_r0) {
            vec3 P = g_pos[px].xyz, n = g_nrm[px].xyz, ks = g_ks[px].xyz;
            vec3 t = lc_tangent(n.x, n.y, n.z), b = lc_bitangent(n.x, n.y, n.z);
            float s_exp = g_alb[px].w;
            vec3 V = -camera_ray_d(dvec2(double(px % u_width), double(px / u_width)) + 0.5LF);
            float offset = ray_offset(bounds_lo(), bounds_hi());
            for (int r = u_r0; r < min(u_r1, c); r++) {
                float u1 = lc_uniform_f(u_seed, uvec2(uint(px), 0u), uint(GLOSSY_STREAM + 2 * r));
                float u2 = lc_uniform_f(u_seed, uvec2(uint(px), 0u), uint(GLOSSY_STREAM + 2 * r + 1));
                vec4 ray = glossy_lobe_ray(n.x, n.y, n.z, t.x, t.y, t.z, b.x, b.y, b.z, V.x, V.y, V.z, s_exp, u1, u2,
                                           c);
                vec3 dir = ray.xyz, w = ks * ray.w;
                if (!any(greaterThan(w, vec3(0.0)))) continue;
                live++;
                vec3 o = P + u_glossy_offset * n;
                float th;
                int k = trace(o, dir, INF, false, th);
                vec3 radiance = u_background;
                if (k < 0) {
                    missed++;
                } else {
                    Surf sf = surface(k, o, dir, th);
                    radiance = sf.base;
                    vec3 bt = lc_tangent(sf.n.x, sf.n.y, sf.n.z), bb = lc_bitangent(sf.n.x, sf.n.y, sf.n.z);
                    int m = lc_refine_cut(sf.p, sf.n, bt, bb, u_bounce_lspp);
                    uvec2 id = uvec2((uint(px) << 20) | uint(r), uint(px) >> 12);
                    for (int s = 0; s < m; s++) {
                        if (!lc_node_live(sf.p, sf.n, bt, bb, lc_cut[s])) continue;
                        float u = lc_uniform_f(u_bounce_seed, id, uint(2 * s));
                        vec2 lp = lc_descend(sf.p, sf.n, bt, bb, lc_cut[s], u);   // (leaf, pdf)
                        int leaf = int(lp.x);
                        vec3 v = lc_sample_estimate(sf.p, sf.n, sf.a, leaf, lp.y);
                        if (v.x + v.y + v.z > 0.0 && (u_shadows == 0 || !occluded(sf.p, sf.n, leaf, offset)))
                            radiance += v;
                    }
                }
                acc += w * radiance;
            }
        }
        if (any(isnan(acc)) || any(isinf(acc))) cnt_add(C_NONFINITE, 1u);
        gloss[px] = vec4(acc, 0.0);
        cnt_add(C_GLOSSY_RAYS, live);
        cnt_add(C_RAYS_PRIMARY, live);
        cnt_add(C_MISSED_RAYS, missed);
    }
    cnt_end();
}
