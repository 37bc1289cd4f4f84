// A screen pass's output: an RGBA32F image (OUT_IMAGE, read by a later pass) or the storage buffer the host
// reads back (3 floats per pixel, row-major: an (H, W, 3) float32 array as is).
#include "screen_decl_gen.glsl"
#if OUT_IMAGE
void screen_out(int i, vec3 c) { imageStore(dst_img, ivec2(i % u_width, i / u_width), vec4(c, 0.0)); }
#else
void screen_out(int i, vec3 c) { dst_buf[3 * i] = c.x; dst_buf[3 * i + 1] = c.y; dst_buf[3 * i + 2] = c.z; }
#endif
