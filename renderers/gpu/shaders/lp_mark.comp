// Which LP pixels are shaded (renderers/pipeline.py LPLayout.shaded_pixels): those of the mask (j < n[c])
// that lp_needed (generated from renderers/_lp.py needed) takes: on the display, or read by a border pixel's
// bilinear fetch (flag bit 2, set from the CPU's list by lp_flags.comp). They are appended to the sample list
// (counter C_SAMPLES) with their camera ray; flags become 1 (shaded) or 0, and unshaded LP pixels are zeroed.
#include "common.glsl"
#include "camera.glsl"
#include "samples.glsl"
#include "lp_cols.glsl"
#include "flags_decl_gen.glsl"
#include "lp_needed_gen.glsl"

void main() {
    cnt_begin();
    uint idx = gid();
    bool need = false;
    dvec2 p = dvec2(0.0);
    if (idx < uint(u_lp_w * u_lp_h)) {
        int i = int(idx) % u_lp_w, j = int(idx) / u_lp_w;
        if (j < col_n(i)) {
            p = lp_position_d(i, j);
            need = lp_needed((flags[idx] & 2u) != 0u, p.x, p.y, u_screen.x, u_screen.y);
            if (!need) cnt_add(C_OFFSCREEN_LP_PIXELS, 1u);
        }
        flags[idx] = need ? 1u : 0u;
        if (!need) store_out(int(idx), vec3(0.0));
    }
    uint slot = append_slot(need, C_SAMPLES);
    if (need) samples[slot] = vec4(camera_ray_d(p), intBitsToFloat(int(idx)));
    cnt_end();
}
