#version 430
// FXAA's luma of every LP pixel: sqrt(clip(exposure Y, 0, 1)) of linear Rec. 709 luminance
// (renderers/antialias.py fxaa_luma).
layout(local_size_x = 64) in;
#include "common.glsl"
#include "constants_gen.glsl"
layout(binding = 4, rgba32f) uniform restrict readonly image2D src;
layout(binding = 6, r32f) uniform restrict writeonly image2D luma;
uniform int u_lp_w;
uniform float u_exposure;

void main() {
    uint i = gid();
    if (i < uint(u_n)) {
        ivec2 p = ivec2(int(i) % u_lp_w, int(i) / u_lp_w);
        vec3 c = imageLoad(src, p).xyz;
        float y = u_exposure * (LUMA_R * c.x + LUMA_G * c.y + LUMA_B * c.z);
        imageStore(luma, p, vec4(sqrt(clamp(y, 0.0, 1.0))));
    }
}
