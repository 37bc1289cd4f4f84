#version 430
// Shading of the selected lights (seed 003 Algorithm 1 line 15; sampling.shade_tile): the Lambertian estimate of
// every sample (generated: _kernels.sample_estimate), a shadow ray for those that contribute (all counted, as on
// the CPU), the sum into the pixel's diffuse radiance (added to it with u_accumulate: sl_gt's passes). A dispatch
// shades the samples [u_s0, u_s1) of each cut (llvmpipe cuts loops short past 65,535 iterations: common.glsl).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"
uniform int u_shadows;
uniform int u_accumulate;
uniform int u_s0;
uniform int u_s1;

void main() {
    cnt_begin();
    int i = int(gid()), px = u_first + i;
    if (i < u_n) {
        vec3 p = g_pos[px].xyz, n = g_nrm[px].xyz, alb = g_alb[px].xyz, c = vec3(0.0);
        float offset = ray_offset(bounds_lo(), bounds_hi());
        uint rays = 0u;
        int drawn = 0;
        for (int s = u_s0; s < min(pix[px].x, u_s1); s++) {
            LcSample e = smp[i * CUT_MAX + s];
            if (e.leaf < 0) continue;
            drawn++;
            vec3 v = lc_sample_estimate(p, n, alb, e.leaf, e.pdf);
            if (v.x + v.y + v.z > 0.0) {
                rays++;
                if (u_shadows == 0 || !occluded(p, n, e.leaf, offset)) c += v;
            }
        }
        if (any(isnan(c)) || any(isinf(c))) cnt_add(C_NONFINITE, 1u);
        bool first = u_s0 == 0;
        rad[px] = (u_accumulate != 0 || !first) ? rad[px] + vec4(c, 0.0) : vec4(c, 0.0);
        pix[px].y = (first ? 0 : pix[px].y) + drawn;
        cnt_add(C_RAYS_SHADOW, rays);
        cnt_add(C_LIGHT_SAMPLES, uint(drawn));
    }
    cnt_end();
}
