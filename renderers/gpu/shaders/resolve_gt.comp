#version 430
// GT pixels of rows [u_y0, u_y0 + u_n / width) from their samples (rows [u_s0, u_s1) of the batch): the box
// filter averages a pixel's own samples; the tent filter (radius 1 px) weights the samples of the 3 x 3
// neighbouring pixels by (1 - |dx|)(1 - |dy|) and normalises (renderers/pipeline.py resolve_samples).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "gt.glsl"
layout(std430, binding = 10) readonly buffer Src { float src[]; };   // 3 floats per sample
layout(std430, binding = 15) writeonly buffer Dst { float dst[]; };  // 3 floats per pixel
uniform int u_width;
uniform int u_y0;
uniform int u_s0;
uniform int u_s1;
uniform int u_tent;

vec3 sample_at(int px, int py, int s) {
    int k = (((py - u_s0) * u_width) + px) * SPP + s;
    return vec3(src[3 * k], src[3 * k + 1], src[3 * k + 2]);
}

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        int px = int(i) % u_width, py = u_y0 + int(i) / u_width;
        vec3 acc = vec3(0.0);
        float wsum = 0.0;
        if (u_tent == 0) {
            for (int s = 0; s < SPP; s++) acc += sample_at(px, py, s);
            wsum = float(SPP);
        } else {
            for (int dy = -1; dy <= 1; dy++) {
                int qy = py + dy;
                if (qy < u_s0 || qy >= u_s1) continue;
                for (int dx = -1; dx <= 1; dx++) {
                    int qx = px + dx;
                    if (qx < 0 || qx >= u_width) continue;
                    for (int s = 0; s < SPP; s++) {
                        vec2 o = vec2(dvec2(dx, dy) + gt_offset(qx, qy, s) - 0.5LF);
                        float w = max(0.0, 1.0 - abs(o.x)) * max(0.0, 1.0 - abs(o.y));
                        acc += w * sample_at(qx, qy, s);
                        wsum += w;
                    }
                }
            }
        }
        vec3 c = acc / wsum;
        int p = py * u_width + px;
        dst[3 * p] = c.x;
        dst[3 * p + 1] = c.y;
        dst[3 * p + 2] = c.z;
    }
    cnt_end();
}
