#version 430
// LS' of seed 003 Algorithm 2 (multires.sort_low_res_samples): each low-resolution pixel's samples with a light
// (leaf >= 0) sorted by leaf offset (stable: ties keep the slot order), with their cut node, pdf and node depth;
// the count goes to pix.w.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lc_buffers.glsl"

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        int q = u_first + int(i);
        uint src = i * uint(CUT_MAX), dst = uint(q) * uint(CUT_MAX);
        int m = pix[q].x, count = 0;
        for (int s = 0; s < m; s++) {
            uvec4 e = smp[src + uint(s)];
            if (int(e.y) < 0) continue;
            uvec4 entry = uvec4(e.y, e.x, e.z, uint(findMSB(int(e.x))));
            int r = count - 1;
            while (r >= 0 && lr_ls[dst + uint(r)].x > entry.x) {
                lr_ls[dst + uint(r + 1)] = lr_ls[dst + uint(r)];
                r--;
            }
            lr_ls[dst + uint(r + 1)] = entry;
            count++;
        }
        pix[q].w = count;
    }
    cnt_end();
}
