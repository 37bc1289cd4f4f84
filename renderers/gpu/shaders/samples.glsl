// A batch of samples: one ray each from u_origin, traced, shaded, shadow-tested and written to its output slot
// (samples.comp). The batch size is u_n, or the value of counter u_count_at when the batch was built on the GPU
// (lp_mark.comp, rep_holes.comp).
layout(std430, binding = 6) buffer Samples { vec4 samples[]; };   // direction | output slot (int bits)
layout(std430, binding = 7) buffer Hits { vec2 hits[]; };         // triangle (int bits; -1: miss) | t
layout(std430, binding = 8) buffer Masks { uint masks[]; };       // MASK_WORDS per sample: lights to test
layout(std430, binding = 9) buffer Partial { vec4 partial[]; };   // radiance without the shadowed lights
#if OUT_IMAGE
// Output slot k is texel (k mod u_out_w, k / u_out_w) of an RGBA32F image (the LP buffer).
layout(binding = 4, rgba32f) uniform restrict writeonly image2D out_img;
uniform int u_out_w;
void store_out(int k, vec3 c) { imageStore(out_img, ivec2(k % u_out_w, k / u_out_w), vec4(c, 0.0)); }
#else
layout(std430, binding = 10) buffer Out { float outbuf[]; };      // 3 floats per output slot
void store_out(int k, vec3 c) { outbuf[3 * k] = c.x; outbuf[3 * k + 1] = c.y; outbuf[3 * k + 2] = c.z; }
#endif
uniform vec3 u_origin;
uniform int u_count_at;

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
