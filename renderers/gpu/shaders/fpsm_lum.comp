#version 430
// Eq 3's input: the luminance of the low-resolution render fb' upsampled bicubically to w x h (fpsm.
// luminance_contrast): the cubic B-spline of the coefficients the CPU prefiltered (scipy's spline filter of fb',
// edges padded by PAD), clipped to fb''s range and at 0.
layout(local_size_x = 64) in;
#include "common.glsl"
#include "lc_buffers.glsl"
#include "fpsm.glsl"
uniform ivec2 u_coef;      // coefficient array: width, height (fb' plus PAD on every side)
uniform vec2 u_scale;      // (w' / w, h' / h)
uniform vec2 u_range;      // fb''s smallest and largest luminance

float bspline3(float t) {
    t = abs(t);
    return t < 1.0 ? 2.0 / 3.0 - t * t + 0.5 * t * t * t : (t < 2.0 ? (2.0 - t) * (2.0 - t) * (2.0 - t) / 6.0 : 0.0);
}

void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {
        int x = int(i) % u_width, y = int(i) / u_width;
        vec2 c = (vec2(x, y) + 0.5) * u_scale - 0.5 + float(PAD);
        ivec2 c0 = ivec2(floor(c));
        float v = 0.0;
        for (int ky = c0.y - 1; ky <= c0.y + 2; ky++) {
            float wy = bspline3(c.y - float(ky));
            for (int kx = c0.x - 1; kx <= c0.x + 2; kx++)
                v += fp_low[clamp(ky, 0, u_coef.y - 1) * u_coef.x + clamp(kx, 0, u_coef.x - 1)] * wy
                     * bspline3(c.x - float(kx));
        }
        fp_px[i].x = max(clamp(v, u_range.x, u_range.y), 0.0);
    }
    cnt_end();
}
