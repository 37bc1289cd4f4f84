#version 430
// LMFR's post anti-aliasing (renderers/antialias.py foveal_gaussian): each pixel takes the Gaussian of its
// eccentricity band (e = atan(c_r r), seed 001 Eq 3): none below the first edge, then radius 1, 2, 5 with
// the CPU's normalised 1-D weights (u_w, band b at offset 11 (b - 1)), edges clamped.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "screen_out.glsl"
layout(binding = 4, rgba32f) uniform restrict readonly image2D src;
uniform int u_height;
uniform vec2 u_gaze;
uniform float u_c_r;
uniform vec3 u_edges;
uniform ivec3 u_radii;
uniform float u_w[33];

vec3 px_at(int x, int y) {
    return imageLoad(src, ivec2(clamp(x, 0, u_width - 1), clamp(y, 0, u_height - 1))).xyz;
}

void main() {
    uint i = gid();
    if (i < uint(u_n)) {
        int x = int(i) % u_width, y = int(i) / u_width;
        float dx = float(x) + 0.5 - u_gaze.x, dy = float(y) + 0.5 - u_gaze.y;
        float e = degrees(atan(u_c_r * sqrt(dx * dx + dy * dy)));
        int b = (e >= u_edges.x ? 1 : 0) + (e >= u_edges.y ? 1 : 0) + (e >= u_edges.z ? 1 : 0);
        vec3 c;
        if (b == 0) {
            c = px_at(x, y);
        } else {
            int r = u_radii[b - 1];
            int o = 11 * (b - 1) + r;
            c = vec3(0.0);
            for (int v = -r; v <= r; v++) {
                vec3 row = vec3(0.0);
                for (int h = -r; h <= r; h++) row += u_w[o + h] * px_at(x + h, y + v);
                c += u_w[o + v] * row;
            }
        }
        screen_out(int(i), c);
    }
}
