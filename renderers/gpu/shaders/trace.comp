#version 430
// Primary visibility: closest hit of each sample's ray (Embree INTERSECT in renderers/tracer.py).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "samples.glsl"

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
        float t;
        int k = trace(u_origin, samples[i].xyz, INF, false, t);
        hits[i] = vec2(intBitsToFloat(k), t);
        cnt_add(C_RAYS_PRIMARY, 1u);
    }
    cnt_end();
}
