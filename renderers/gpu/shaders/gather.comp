#version 430
// Final radiance of each sample (renderers/_shade.py accumulate): partial + the lights that passed the shadow
// test, written to the sample's output slot; non-finite values are counted (the host refuses them).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "samples.glsl"

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
        vec3 c = partial[i].xyz;
        int k = floatBitsToInt(hits[i].x);
        if (k >= 0) {
            Surf s = surface(k, u_origin, samples[i].xyz, hits[i].y);
            for (int w = 0; w < MASK_WORDS; w++) {
                uint m = masks[i * uint(MASK_WORDS) + uint(w)];
                while (m != 0u) {
                    int b = findLSB(m);
                    m &= m - 1u;
                    c += light_contribution(s, w * 32 + b);
                }
            }
        }
        if (any(isnan(c)) || any(isinf(c))) cnt_add(C_NONFINITE, 1u);
        store_out(floatBitsToInt(samples[i].w), c);
    }
    cnt_end();
}
