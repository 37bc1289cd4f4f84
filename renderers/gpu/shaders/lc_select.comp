#version 430
// One light per cut node (seed 003 Algorithm 2, _kernels.sample_cuts / multires.select_lights): with MULTIRES,
// a low-resolution sample under the node is reused with probability 1 - map[p] (multires.reuse_sample), else the
// light is drawn by hierarchical importance sampling from the node (Algorithm 2 line 9). Nodes that cannot
// contribute get no light (leaf -1). Random slots: 2s for the descent, 2s + 1 for Algorithm 2's rad.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "scene.glsl"
#include "lightcuts.glsl"
#include "lc_buffers.glsl"
uniform int u_width;       // of the frame
uniform dvec2 u_lr_scale;  // (w' / w, h' / h)
uniform int u_lr_width;
uniform int u_lr_height;

#if MULTIRES
// multires.lrls: index of the first LS'[q] entry (sorted by leaf) in [lo, hi], or -1.
int lrls(uint base, int count, uint lo, uint hi) {
    int a = 0, b = count;
    while (a < b) {
        int mid = (a + b) / 2;
        if (lr_ls[base + uint(mid)].x < lo) a = mid + 1;
        else b = mid;
    }
    return (a < count && lr_ls[base + uint(a)].x <= hi) ? a : -1;
}

// multires.reuse_sample: the reused sample for cut node `node` (Eq 9's leaf range [lo, hi]) and its probability.
int reuse_sample(int node, uint base, int count, int first, uint hi, float u, out float pdf) {
    int dn = findMSB(node);
    uvec4 e = lr_ls[base + uint(first)];
    if (int(e.w) < dn) {   // (a) one low-resolution cut node above `node`
        pdf = uintBitsToFloat(e.z) * node_inten(int(e.y)) / node_inten(node);
        return first;
    }
    float total = 0.0, pick_w = 0.0;   // (b) cut nodes partitioning node's subtree, drawn by intensity
    int pick = first;
    for (int j = first; j < count; j++) {
        uvec4 f = lr_ls[base + uint(j)];
        if (f.x > hi) break;
        float wj = node_inten(int(f.y));
        if (wj > 0.0) {
            total += wj;
            float r = wj / total;
            if (u < r) {
                pick = j;
                pick_w = wj;
                u = u / r;
            } else {
                u = (u - r) / (1.0 - r);
            }
            u = min(u, LC_ONE_MINUS_F);
        }
    }
    if (total <= 0.0) {
        pdf = uintBitsToFloat(e.z);
        return first;
    }
    pdf = uintBitsToFloat(lr_ls[base + uint(pick)].z) * pick_w / total;
    return pick;
}
#endif

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        int px = u_first + int(i);
        int m = pix[px].x;
        uint id = u_id_base + uint(px);
        int reused = 0;
        vec3 p = g_pos[px].xyz, n = g_nrm[px].xyz, t, b;
        lc_frame(n, t, b);
#if MULTIRES
        float fmap = intBitsToFloat(ctl[px].z);
        int qx = min(int(double(px % u_width) * u_lr_scale.x), u_lr_width - 1);
        int qy = min(int(double(px / u_width) * u_lr_scale.y), u_lr_height - 1);
        int q = qy * u_lr_width + qx;
        uint base = uint(q) * uint(CUT_MAX);
        int count = lr_pix[q].w;
#endif
        for (int s = 0; s < m; s++) {
            uint k = i * uint(CUT_MAX) + uint(s);
            int node = int(smp[k].x);
            int leaf = -1;
            float pdf = 0.0;
            if (node_live(p, n, t, b, node)) {
                bool done = false;
#if MULTIRES
                float rad = lc_uniform_f(u_seed, uvec2(id, 0u), uint(2 * s + 1));
                if (rad <= 1.0 - fmap && count > 0) {
                    int span = 1 << (u_levels - (findMSB(node) + 1));   // Eq 9
                    uint lo = uint(node * span), hi = lo + uint(span - 1);
                    int first = lrls(base, count, lo, hi);
                    if (first >= 0) {
                        int j = reuse_sample(node, base, count, first, hi,
                                             fmap < 1.0 ? min(rad / (1.0 - fmap), LC_ONE_MINUS_F) : 0.0, pdf);
                        leaf = int(lr_ls[base + uint(j)].x);
                        reused++;
                        done = true;
                    }
                }
#endif
                if (!done) leaf = descend(p, n, t, b, node, lc_uniform_f(u_seed, uvec2(id, 0u), uint(2 * s)), pdf);
            }
            smp[k].y = uint(leaf);
            smp[k].z = floatBitsToUint(pdf);
        }
        pix[px].z = reused;
        cnt_add(C_REUSED, uint(reused));
    }
    cnt_end();
}
