#version 430
// GT samples of screen rows [u_y0, u_y0 + u_n / (width SPP)): SPP per pixel (gt.glsl); slot u_slot_base + index.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "camera.glsl"
#include "samples.glsl"
#include "gt.glsl"
uniform int u_y0;
uniform int u_width;
uniform int u_slot_base;

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        int pix = int(i) / SPP, s = int(i) - pix * SPP;
        int px = pix % u_width, py = u_y0 + pix / u_width;
        dvec2 xy = dvec2(px, py) + gt_offset(px, py, s);
        samples[i] = vec4(camera_ray_d(xy), intBitsToFloat(u_slot_base + int(i)));
    }
    cnt_end();
}
