// A batch of samples: one ray each from u_origin, traced, shaded, shadow-tested and written to its output slot
// (samples.comp). The batch size is u_n, or the value of counter u_count_at when the batch was built on the GPU
// (lp_mark.comp, rep_holes.comp).
#include "samples_decl_gen.glsl"
#if OUT_IMAGE
void store_out(int k, vec3 c) { imageStore(out_img, ivec2(k % u_out_w, k / u_out_w), vec4(c, 0.0)); }
#else
void store_out(int k, vec3 c) { outbuf[3 * k] = c.x; outbuf[3 * k + 1] = c.y; outbuf[3 * k + 2] = c.z; }
#endif

uint sample_count() {
    return u_count_at >= 0 ? counters[u_count_at] : uint(u_n);
}

// Append `want` to the list whose length is counter `at`: one global atomic per workgroup (stream compaction).
shared uint s_append_base;
shared uint s_append_n;
uint append_slot(bool want, int at) {
    if (gl_LocalInvocationIndex == 0u) s_append_n = 0u;
    barrier();
    uint mine = want ? atomicAdd(s_append_n, 1u) : 0u;
    barrier();
    if (gl_LocalInvocationIndex == 0u) s_append_base = atomicAdd(counters[at], s_append_n);
    barrier();
    return s_append_base + mine;
}
