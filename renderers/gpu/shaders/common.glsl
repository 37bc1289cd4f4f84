// Shared by every compute shader: the 1-D invocation index and the per-workgroup counter reduction.
// COUNTERS (the number of counters) and the C_* indices are defined by the host (renderers/gpu/frame.py).
#include "common_decl_gen.glsl"

// Workgroup g (in dispatch order) takes block (g % rows) * stripes + g / rows of the problem's blocks of
// gl_WorkGroupSize.x invocations, the host dispatching rows * stripes groups (renderers/gpu/context.py STRIPES):
// llvmpipe gives each thread a contiguous range of workgroups, which then spans every part of the image, so
// uneven work (glossy pixels in one corner) is shared. Groups past rows * stripes (the 2-D grid's rounding) get
// an index past every problem (no block).
uint gid() {
    uint g = gl_WorkGroupID.x + gl_WorkGroupID.y * uint(u_groups_x);
    uint rows = uint(u_group_rows), stripes = uint(u_stripes);
    if (g >= rows * stripes) return 0x7FFFFFFFu;  // above any u_n, as uint and as int
    return ((g % rows) * stripes + g / rows) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
}

#ifdef COUNTERS
#include "counters_decl_gen.glsl"
// Counts add up in shared memory and reach the global buffer once per workgroup: millions of atomics on one
// address would serialise on a GPU. Call cnt_begin() and cnt_end() in uniform control flow (no early return).
shared uint s_cnt[COUNTERS];
void cnt_begin() {
    if (gl_LocalInvocationIndex < uint(COUNTERS)) s_cnt[gl_LocalInvocationIndex] = 0u;
    barrier();
}
void cnt_add(int k, uint v) {
    if (v != 0u) atomicAdd(s_cnt[k], v);
}
// llvmpipe (Mesa's software OpenGL) ends every loop of an invocation after its first pass once the invocation has
// run 65,535 loop iterations in all (gallivm's LP_MAX_TGSI_LOOP_ITERATIONS, shared by all its loops), so work
// past that point is silently wrong. The host sets u_loop_probe to 2 (renderers/gpu/context.py): this loop then
// runs twice unless the limit was reached, which C_LOOP_LIMIT counts and the host refuses (frame.py). GPUs have
// no such limit; there the check costs two iterations.
void cnt_end() {
    int probe = 0;
    for (int q = 0; q < u_loop_probe; q++) probe++;
    if (probe < u_loop_probe) cnt_add(C_LOOP_LIMIT, 1u);
    barrier();
    if (gl_LocalInvocationIndex < uint(COUNTERS)) {
        uint v = s_cnt[gl_LocalInvocationIndex];
        if (v != 0u) atomicAdd(counters[gl_LocalInvocationIndex], v);
    }
}
#endif
