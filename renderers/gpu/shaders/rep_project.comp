// Project each left sample's hit point (a miss: its direction at infinity) into the right view, map it into
// the LP buffer (u by the forward mapping, phi the polar angle) and splat its depth into the LP pixel holding
// it (renderers/pipeline.py LPLayout.lp_coords; camera.glsl is the right camera, the screen position
// renderers/projection.py plane_to_screen).
#include "common.glsl"
#include "samples.glsl"
#include "lp_cols.glsl"
#include "lp_map.glsl"
#include "rep.glsl"
#include "camera.glsl"

void main() {
    cnt_begin();
    uint i = gid();
    if (i < sample_count()) {
        vec3 d = samples[i].xyz;
        int idx = floatBitsToInt(samples[i].w);
        bool hit = floatBitsToInt(hits[i].x) >= 0;
        vec3 rel = hit ? u_left_pos + d * hits[i].y - u_right_pos : d;
        float zf = dot(rel, vec3(u_cam_f));
        vec4 wv = vec4(0.0, 0.0, REP_INF, intBitsToFloat(-1));
        if (zf > 0.0) {
            float sx = dot(rel, vec3(u_cam_r)) / zf, sy = dot(rel, vec3(u_cam_u)) / zf;
            vec2 off = proj_plane_to_screen(sx, sy, u_screen.x, u_screen.y, float(u_tan)) - u_gaze;
            float u = lp_u(off.x, off.y), phi = lp_angle(off.x, off.y);
            int c = clamp(int(floor(u)), 0, u_w_eff - 1);
            vec4 col = cols(c);
            int r = wrap_row(int(floor(phi * col.y)), max(int(col.z), 1));
            int lin = r * u_lp_w + c;
            float z = hit ? zf : REP_INF;
            wv = vec4(u, phi, z, intBitsToFloat(lin));
            atomicMin(zbuf[lin], floatBitsToUint(z));
            covered[lin] = 1u;
        }
        warp[idx] = wv;
    }
    cnt_end();
}
