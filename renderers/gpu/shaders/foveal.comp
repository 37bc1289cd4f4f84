// LMFR's post anti-aliasing (renderers/antialias.py foveal_gaussian): aa_foveal_pixel, generated from antialias.py,
// with the band of the eccentricity e = atan(c_r r) (seed 001 Eq 3) and the CPU's weights (FOVEAL_WEIGHTS).
#include "common.glsl"
#include "screen_out.glsl"
#include "filters_decl_gen.glsl"
#define px_at(y, x) imageLoad(src, ivec2(x, y))
#include "gauss_gen.glsl"
#include "foveal_gen.glsl"

void main() {
    uint i = gid();
    if (i < uint(u_n)) {
        int x = int(i) % u_width, y = int(i) / u_width;
        float dx = float(x) + 0.5 - u_gaze.x, dy = float(y) + 0.5 - u_gaze.y;
        int b = aa_foveal_band(degrees(atan(u_c_r * sqrt(dx * dx + dy * dy))));
        screen_out(int(i), vec3(aa_foveal_pixel(y, x, 0, b, u_height, u_width),
            aa_foveal_pixel(y, x, 1, b, u_height, u_width), aa_foveal_pixel(y, x, 2, b, u_height, u_width)));
    }
}
