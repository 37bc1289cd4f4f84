// The one-bounce glossy pass (seed 003 Algorithm 1 lines 16-17, FoveatedPT; renderers/lightcuts/glossy.py):
// for every glossy pixel its rays of slots [u_r0, u_r1) (of u_rspp, or ctl.y per pixel), each a Blinn-Phong
// half-vector sample weighted k_s (s + 8)(n.w_i)(v.h) / ((s + 1) count) (glossy.lobe_sample, generated:
// glossy_gen.glsl), traced to its first hit and shaded there with emission + ambient + stochastic lightcuts of
// u_bounce_lspp nodes (CUT_MAX) with shadow rays by the CPU's pixel kernels (the hit's gloss is not followed).
// Rays below the surface or of zero weight are not traced. Random numbers: slots 2^24 + 2r, 2^24 + 2r + 1 of the
// pixel for the lobe; the bounce's lightcuts use stream u_bounce_seed and id (pixel << 20) + r, as on the CPU.
#include "common.glsl"
#include "scene.glsl"
#include "camera.glsl"
#include "lightcuts.glsl"
#include "lc_buffers.glsl"
#include "glossy_gen.glsl"
// A bounce's point (the ray's hit), id, cut size and samples, read by the CPU's pixel kernels cut_pixel,
// sample_pixel and shade_pixel (lc_bounce_gen.glsl); lcb_blocked(s) is shade_pixel's shadow ray of sample s.
vec3 bn_p, bn_n, bn_a;
uvec2 bn_id;
int bn_m, bn_leaf[CUT_MAX];
float bn_pdf[CUT_MAX], offset;
bool lcb_blocked(int s) { return u_shadows != 0 && occluded(bn_p, bn_n, bn_leaf[s], offset); }
#include "lc_bounce_gen.glsl"

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
            float s_exp = g_alb[px].w;
            vec3 V = -camera_ray_d(dvec2(double(px % u_width), double(px / u_width)) + 0.5LF);
            offset = ray_offset(bounds_lo(), bounds_hi());
            for (int r = u_r0; r < min(u_r1, c); r++) {
                vec4 ray = glossy_lobe_sample(u_seed, uvec2(uint(px), 0u), r, n.x, n.y, n.z, V.x, V.y, V.z, s_exp, c);
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
                    bn_p = sf.p, bn_n = sf.n, bn_a = sf.a, bn_id = uvec2((uint(px) << 20) | uint(r), uint(px) >> 12);
                    bn_m = lcb_cut_pixel(0);
                    lcb_sample_pixel(0, u_bounce_seed);
                    radiance = sf.base + lcb_shade_pixel(0, 0, bn_m).xyz;
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
