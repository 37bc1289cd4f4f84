// G-buffer of the lightcuts renderers (renderers/lightcuts/plugin.py Hits) for the rays through pixel positions
// (i + 0.5, j + 0.5) u_step: the pixel centres (step 1) or, for the low-resolution pass of seed 003 Algorithm 1
// line 7, the centres of the w/8 x h/8 pixels on the screen. Hit position, normal facing the viewer, textured
// albedo (0 for metallic), specular colour and exponent, glossy flag, emission + ambient (background on a miss).
// The frame's pass (u_full) also counts the shading points and bounds the hit points (the shadow-ray offset).
#include "common.glsl"
#include "scene.glsl"
#include "camera.glsl"
#include "lc_buffers.glsl"
shared uint s_lo[3];
shared uint s_hi[3];

void main() {
    cnt_begin();
    if (gl_LocalInvocationIndex < 3u) {
        s_lo[gl_LocalInvocationIndex] = 0xFFFFFFFFu;
        s_hi[gl_LocalInvocationIndex] = 0u;
    }
    barrier();
    uint i = gid();
    if (i < uint(u_n)) {
        dvec2 xy = (dvec2(double(int(i) % u_width), double(int(i) / u_width)) + 0.5LF) * u_step;
        vec3 d = camera_ray_d(xy);
        float t;
        int k = trace(u_origin, d, INF, false, t);
        cnt_add(C_RAYS_PRIMARY, 1u);
        if (k < 0) {
            g_pos[i] = vec4(0.0);
            g_nrm[i] = vec4(0.0);
            g_alb[i] = vec4(0.0);
            g_ks[i] = vec4(0.0);
            g_base[i] = vec4(u_background, 0.0);
            cnt_add(C_MISSED_RAYS, 1u);
        } else {
            Surf s = surface(k, u_origin, d, t);
            g_pos[i] = vec4(s.p, 1.0);
            g_nrm[i] = vec4(s.n, s.glossy ? 1.0 : 0.0);
            g_alb[i] = vec4(s.a, s.s_exp);
            g_ks[i] = vec4(s.ks, 0.0);
            g_base[i] = vec4(s.base, 0.0);
            if (u_full != 0) {
                cnt_add(C_SHADING_POINTS, 1u);
                for (int a = 0; a < 3; a++) {
                    atomicMin(s_lo[a], float_key(s.p[a]));
                    atomicMax(s_hi[a], float_key(s.p[a]));
                }
            }
        }
    }
    barrier();
    if (u_full != 0 && gl_LocalInvocationIndex < 3u) {
        atomicMin(bounds[gl_LocalInvocationIndex], s_lo[gl_LocalInvocationIndex]);
        atomicMax(bounds[3u + gl_LocalInvocationIndex], s_hi[gl_LocalInvocationIndex]);
    }
    cnt_end();
}
