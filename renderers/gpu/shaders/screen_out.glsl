// A screen pass's output: an RGBA32F image (OUT_IMAGE, read by a later pass) or the storage buffer the host
// reads back (3 floats per pixel, row-major: an (H, W, 3) float32 array as is).
uniform int u_width;
#if OUT_IMAGE
layout(binding = 5, rgba32f) uniform restrict writeonly image2D dst_img;
void screen_out(int i, vec3 c) { imageStore(dst_img, ivec2(i % u_width, i / u_width), vec4(c, 0.0)); }
#else
layout(std430, binding = 15) writeonly buffer Dst { float dst[]; };
void screen_out(int i, vec3 c) { dst[3 * i] = c.x; dst[3 * i + 1] = c.y; dst[3 * i + 2] = c.z; }
#endif
