// Needed right LP pixels that received nothing become the re-shading list (counter C_HOLES; rays from the
// right eye); the other uncovered pixels are zeroed.
#include "common.glsl"
#include "camera.glsl"
#include "samples.glsl"
#include "lp_cols.glsl"
#include "rep.glsl"

void main() {
    cnt_begin();
    uint idx = gid();
    bool hole = false;
    if (idx < uint(u_lp_w * u_lp_h) && covered[idx] == 0u) {
        hole = (flags[idx] & 1u) != 0u;
        if (!hole) store_out(int(idx), vec3(0.0));
    }
    uint slot = append_slot(hole, C_HOLES);
    if (hole) {
        dvec2 xy = lp_position_d(int(idx) % u_lp_w, int(idx) / u_lp_w);
        samples[slot] = vec4(camera_ray_d(xy), intBitsToFloat(int(idx)));
    }
    cnt_end();
}
