#version 430
// renderers/pipeline.py fill_unshaded: each unshaded LP pixel takes the last shaded pixel of its row at a
// smaller column (column 0 if there is none), so the LP filters do not blend black into the display's border.
layout(local_size_x = 64) in;
#include "common.glsl"
layout(binding = 4, rgba32f) uniform restrict image2D lp;
layout(std430, binding = 14) readonly buffer Flags { uint flags[]; };
uniform int u_lp_w;

void main() {
    int j = int(gid());
    if (j < u_n) {
        int src = 0;
        for (int c = 0; c < u_lp_w; c++) {
            if ((flags[j * u_lp_w + c] & 1u) != 0u) src = c;
            else if (src != c) imageStore(lp, ivec2(c, j), imageLoad(lp, ivec2(src, j)));
        }
    }
}
