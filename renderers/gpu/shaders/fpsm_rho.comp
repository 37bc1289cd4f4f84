#version 430
// rho of Eq 4-7 under the reading READING (0 derived, 1 blur; fpsm.rho_map), +inf where Eq 4 holds for every rho,
// and the frame's smallest and largest finite rho (Eq 8). READING 2 (retained) stores the map itself:
// clip((M - alpha) / (1 - alpha), 0, 1). M = max(fb_st, fb_l), D = the squared deviations from the 5 x 5 means
// (D <= D_TOL taken as 0).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lc_buffers.glsl"
#include "fpsm.glsl"
uniform float u_alpha;
shared uint s_lo;
shared uint s_hi;

void main() {
    cnt_begin();
    if (gl_LocalInvocationIndex == 0u) {
        s_lo = 0xFFFFFFFFu;
        s_hi = 0u;
    }
    barrier();
    uint i = gid();
    if (i < uint(u_n)) {
        int x = int(i) % u_width, y = int(i) / u_width;
        vec2 f = fp_px[i].yz, mean = vec2(0.0);
        for (int dy = -2; dy <= 2; dy++) {
            int yy = clamp(y + dy, 0, u_height - 1);
            for (int dx = -2; dx <= 2; dx++)
                mean += binom(dy) * binom(dx) * fp_px[yy * u_width + clamp(x + dx, 0, u_width - 1)].yz;
        }
        vec2 dev = f - mean;
        float d = dot(dev, dev);
        d = d > D_TOL ? d : 0.0;
        float m = max(f.x, f.y);
        float inf = 1.0 / 0.0;
        float neg2ln = -2.0 * log(m > u_alpha ? m - u_alpha : 0.5);
        float rho;
#if READING == 0
        rho = m > u_alpha ? sqrt(d / neg2ln) : inf;
#elif READING == 1
        rho = (m > u_alpha && d > 0.0) ? sqrt(neg2ln / d) : inf;
#else
        rho = clamp((m - u_alpha) / (1.0 - u_alpha), 0.0, 1.0);
#endif
        fp_px[i].w = rho;
#if READING != 2
        if (!isinf(rho)) {
            atomicMin(s_lo, float_key(rho));
            atomicMax(s_hi, float_key(rho));
        }
#endif
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u && s_lo <= s_hi) {
        atomicMin(bounds[RHO_LO], s_lo);
        atomicMax(bounds[RHO_HI], s_hi);
    }
    cnt_end();
}
