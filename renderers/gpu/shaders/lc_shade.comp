// Shading of the selected lights (seed 003 Algorithm 1 line 15; sampling.shade_tile): the generated
// _kernels.shade_pixel sums the Lambertian estimates of the samples [u_s0, u_s1) of the pixel's cut whose shadow ray
// (lc_blocked, cast for every contributing sample and counted, as on the CPU) is free, into the pixel's diffuse
// radiance (added to it with u_accumulate: sl_gt's passes). A dispatch shades a slice of each cut: llvmpipe cuts an
// invocation's loops short past 65,535 iterations (common.glsl).
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"
uint rays = 0u;
float offset;

bool lc_blocked(int i, int s) {   // shade_pixel's visibility of the tile's sample (i, s)
    rays++;
    int px = u_first + i;
    return u_shadows != 0 && occluded(g_pos[px].xyz, g_nrm[px].xyz, smp[i * CUT_MAX + s].leaf, offset);
}
#include "lc_shade_gen.glsl"

void main() {
    cnt_begin();
    int i = int(gid()), px = u_first + i;
    if (i < u_n) {
        offset = ray_offset(bounds_lo(), bounds_hi());
        vec4 c = lc_shade_pixel(i, u_s0, min(pix[px].x, u_s1));   // radiance, samples with a light
        if (any(isnan(c.xyz)) || any(isinf(c.xyz))) cnt_add(C_NONFINITE, 1u);
        bool first = u_s0 == 0;
        rad[px] = (u_accumulate != 0 || !first) ? rad[px] + vec4(c.xyz, 0.0) : vec4(c.xyz, 0.0);
        pix[px].y = (first ? 0 : pix[px].y) + int(c.w);
        cnt_add(C_RAYS_SHADOW, rays);
        cnt_add(C_LIGHT_SAMPLES, uint(c.w));
    }
    cnt_end();
}
