// The passes of the FPSM (renderers/gpu/fpsm.py; seed 003 §3.1, Eq 1-8), after the G-buffer: the per-pixel
// formulas are renderers/lightcuts/fpsm.py's, generated (fpsm_gen.glsl); here only the images they read, the
// frame's extreme finite rho (Eq 8) and the controls. PASS: 1 fb' upsampled, 2-3 pyramid levels 1-2, 4 features,
// 5 rho (READING 0 derived, 1 blur; 2 retained: the map), 6 controls (READING 3: the AFSM, fb_st).
#include "common.glsl"
#include "lc_buffers.glsl"
#include "fpsm_decl_gen.glsl"
const int RHO_LO = 6, RHO_HI = 7;   // keys of the smallest and largest finite rho after the G-buffer's bounds

// fpsm.blur5's img[c, k]: fb' upsampled (level 0), level 1, or fb_st | fb_l.
float fp_img(int c, int k) { return PASS == 2 ? fp_px[k].x : (PASS == 3 ? fp_low[u_g1_at + k] : fp_px[k][1 + c]); }

vec2 to_screen(mat4 m, vec3 p, out bool ok) {
    vec4 c = m * vec4(p, 1.0);
    ok = c.w > 1e-12;
    float w = ok ? c.w : 1.0;
    return vec2((c.x / w + 1.0) * float(u_width) / 2.0, (1.0 - c.y / w) * float(u_height) / 2.0);
}

// fpsm.gradient_at's gbuf[k, c]: Eq 1's normal, albedo and screen velocity (fpsm.screen_velocity; 0 on a miss).
float fp_gbuf(int k, int c) {
    if (c < 6) return c < 3 ? g_nrm[k][c] : g_alb[k][c - 3];
    bool ok0, ok1;
    vec2 v = to_screen(u_vp, g_pos[k].xyz, ok0) - to_screen(u_vp_prev, g_pos[k].xyz, ok1);
    return u_moving != 0 && g_pos[k].w > 0.0 && ok0 && ok1 ? v[c - 6] : 0.0;
}
#include "fpsm_gen.glsl"
shared uint s_lo, s_hi;

void main() {
    cnt_begin();
    if (gl_LocalInvocationIndex == 0u) {
        s_lo = 0xFFFFFFFFu;
        s_hi = 0u;
    }
    barrier();
    uint i = gid();
    int x = int(i) % u_width, y = int(i) / u_width;
    if (i < uint(u_n)) {
#if PASS == 1
        fp_px[i].x = fpsm_resample_at(0, u_coef.x, u_coef.y, x, y, u_scale.x, u_scale.y, float(FPSM_PAD), 3,
                                      u_range.x, u_range.y);
#elif PASS <= 3
        ivec2 src = PASS == 2 ? ivec2(u_width, u_height) : u_g1, dst = PASS == 2 ? u_g1 : u_g2;
        fp_low[(PASS == 2 ? u_g1_at : u_g2_at) + int(i)] = fpsm_blur5(0, 2 * (int(i) % dst.x), 2 * (int(i) / dst.x),
                                                                      src.x, src.y);
#elif PASS == 4
        float fb_f = fpsm_acuity(atan(u_c_r * length(vec2(x, y) + 0.5 - u_gaze)));
        float l = 0.0;
#if LUMINANCE  // LP_1 = fb' - level 1 and LP_3 = level 2, upsampled linearly (not clipped to the level's range)
        vec2 s1 = vec2(u_g1) / vec2(u_width, u_height), s2 = vec2(u_g2) / vec2(u_width, u_height);
        float band = fp_px[i].x - fpsm_resample_at(u_g1_at, u_g1.x, u_g1.y, x, y, s1.x, s1.y, 0.0, 1, -1e38, 1e38);
        float residual = fpsm_resample_at(u_g2_at, u_g2.x, u_g2.y, x, y, s2.x, s2.y, 0.0, 1, -1e38, 1e38);
        l = fpsm_feature(fb_f, fpsm_contrast_at(band, residual, u_eps));
#endif
        fp_px[i].yz = vec2(fpsm_feature(fb_f, fpsm_gradient_at(x, y, u_width, u_height, 8)), l);
#elif PASS == 5
        float rho = fpsm_rho_at(fp_px[i].y, fp_px[i].z, fpsm_blur5(0, x, y, u_width, u_height),
                                fpsm_blur5(1, x, y, u_width, u_height), u_alpha, READING);
        fp_px[i].w = rho;
        if (!isinf(rho)) {
            atomicMin(s_lo, float_key(rho));
            atomicMax(s_hi, float_key(rho));
        }
#else
        float map = READING == 3 ? fp_px[i].y : fp_px[i].w;
        if (READING < 2) map = fpsm_map_at(map, key_float(bounds[RHO_LO]), key_float(bounds[RHO_HI]));
        ctl[i] = ivec4(g_pos[i].w > 0.0 ? fpsm_budget(map, u_max_lspp, 1) : 0,
                       fpsm_budget(map, u_max_rspp, READING == 3 ? 1 : 0), floatBitsToInt(map), 0);
#endif
    }
    barrier();
    if (PASS == 5 && gl_LocalInvocationIndex == 0u && s_lo <= s_hi) {
        atomicMin(bounds[RHO_LO], s_lo);
        atomicMax(bounds[RHO_HI], s_hi);
    }
    cnt_end();
}
