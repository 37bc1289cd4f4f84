#version 430
// The feature maps of seed 003 §3.1 at every pixel: Eq 2's acuity fb_f (eccentricity atan(c_r r), radians),
// Eq 1's spatiotemporal feature fb_st = max(fb_f, |grad fb_n|, |grad fb_a|, |grad fb_v|) (3 x 3 Sobel magnitude / 8,
// the largest over channels, edges replicated; the velocity is each hit's screen motion from the previous camera,
// 0 without one) and, with LUMINANCE, Eq 3's fb_l = max(fb_f, |LP_1| / (LP_3 + eps)) (fpsm.luminance_contrast).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "fpsm_gen.glsl"
#include "lc_buffers.glsl"
#include "fpsm.glsl"
uniform vec2 u_gaze;
uniform float u_c_r;
uniform int u_moving;
uniform mat4 u_vp;         // world -> clip of this frame's camera and of the previous one (plugin.view_projection)
uniform mat4 u_vp_prev;
uniform float u_eps;

vec2 to_screen(mat4 m, vec3 p, out bool ok) {
    vec4 c = m * vec4(p, 1.0);
    ok = c.w > 1e-12;
    float w = ok ? c.w : 1.0;
    return vec2((c.x / w + 1.0) * float(u_width) / 2.0, (1.0 - c.y / w) * float(u_height) / 2.0);
}

// The 8 channels of the gradient features at pixel k: normal, albedo, velocity.
void channels(int k, out vec3 n, out vec3 a, out vec2 v) {
    n = g_nrm[k].xyz;
    a = g_alb[k].xyz;
    v = vec2(0.0);
    if (u_moving != 0 && g_pos[k].w > 0.0) {
        bool ok0, ok1;
        vec2 now = to_screen(u_vp, g_pos[k].xyz, ok0), before = to_screen(u_vp_prev, g_pos[k].xyz, ok1);
        if (ok0 && ok1) v = now - before;
    }
}

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        int x = int(i) % u_width, y = int(i) / u_width;
        float fb_f = fpsm_acuity(atan(u_c_r * length(vec2(x, y) + 0.5 - u_gaze)));   // Eq 2, generated
        vec3 gxn = vec3(0.0), gyn = vec3(0.0), gxa = vec3(0.0), gya = vec3(0.0);
        vec2 gxv = vec2(0.0), gyv = vec2(0.0);
        for (int dy = -1; dy <= 1; dy++) {
            for (int dx = -1; dx <= 1; dx++) {
                if (dx == 0 && dy == 0) continue;
                int k = clamp(y + dy, 0, u_height - 1) * u_width + clamp(x + dx, 0, u_width - 1);
                vec3 n, a;
                vec2 v;
                channels(k, n, a, v);
                float wx = float(dx) * (dy == 0 ? 2.0 : 1.0), wy = float(dy) * (dx == 0 ? 2.0 : 1.0);
                gxn += wx * n;
                gyn += wy * n;
                gxa += wx * a;
                gya += wy * a;
                gxv += wx * v;
                gyv += wy * v;
            }
        }
        float g = 0.0;
        for (int c = 0; c < 3; c++) g = max(g, max(length(vec2(gxn[c], gyn[c])), length(vec2(gxa[c], gya[c]))));
        for (int c = 0; c < 2; c++) g = max(g, length(vec2(gxv[c], gyv[c])));
        float st = clamp(max(fb_f, g / 8.0), 0.0, 1.0);
        float l = 0.0;
#if LUMINANCE
        float band = fp_px[i].x - level_at(u_g1_at, u_g1, x, y);
        float residual = max(level_at(u_g2_at, u_g2, x, y), 0.0);
        float contrast = abs(band) / (residual + u_eps);
        contrast = isnan(contrast) || isinf(contrast) ? 1.0 : contrast;
        l = clamp(max(fb_f, clamp(contrast, 0.0, 1.0)), 0.0, 1.0);
#endif
        fp_px[i].yz = vec2(st, l);
    }
    cnt_end();
}
