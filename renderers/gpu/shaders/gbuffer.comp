#version 430
// Deferred pipeline (seed 001 §3.4): visibility of every screen pixel centre (triangle, t).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "camera.glsl"
layout(std430, binding = 15) writeonly buffer GBuf { vec2 gbuf[]; };
uniform vec3 u_origin;
uniform int u_width;

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        dvec2 xy = dvec2(double(int(i) % u_width), double(int(i) / u_width)) + 0.5LF;
        float t;
        int k = trace(u_origin, camera_ray_d(xy), INF, false, t);
        gbuf[i] = vec2(intBitsToFloat(k), t);
        cnt_add(C_RAYS_PRIMARY, 1u);
    }
    cnt_end();
}
