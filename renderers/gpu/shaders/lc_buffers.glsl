// Per-pixel buffers of the lightcuts passes (renderers/gpu/lightcuts.py). Pixel p of the frame is entry p; a
// pass over a tile of pixels sees its sample lists at (p - u_first) * CUT_MAX + s. Shaders use only the ones
// they need (inactive blocks take no binding).
layout(std430, binding = 0) buffer GPos { vec4 g_pos[]; };    // hit position | valid (1 or 0)
layout(std430, binding = 1) buffer GNrm { vec4 g_nrm[]; };    // unit normal facing the viewer | glossy (1 or 0)
layout(std430, binding = 2) buffer GAlb { vec4 g_alb[]; };    // diffuse albedo (0 when metallic) | exponent
layout(std430, binding = 3) buffer GKs { vec4 g_ks[]; };      // specular colour (0 unless glossy/metallic) | 0
layout(std430, binding = 4) buffer GBase { vec4 g_base[]; };  // emission + ambient; the background on a miss
layout(std430, binding = 6) buffer Bounds { uint bounds[]; }; // G-buffer points' box: min xyz, max xyz (ordered)
layout(std430, binding = 7) buffer Ctl { ivec4 ctl[]; };      // cut budget #L | glossy rays | FPSM map (bits) | 0
layout(std430, binding = 8) buffer Smp { uvec4 smp[]; };      // cut node | leaf (-1: none) | pdf (bits) | 0
layout(std430, binding = 9) buffer Pix { ivec4 pix[]; };      // cut size | light samples | reused | LS' count
layout(std430, binding = 10) buffer LowSmp { uvec4 lr_ls[]; };// LS': leaf | cut node | pdf (bits) | node depth
layout(std430, binding = 11) buffer LowPix { ivec4 lr_pix[]; };
layout(std430, binding = 12) buffer Rad { vec4 rad[]; };      // direct diffuse radiance
layout(std430, binding = 13) buffer Gloss { vec4 gloss[]; };  // glossy radiance

uniform int u_first;       // first pixel of the tile
uniform uvec2 u_seed;      // random stream (64 bits: lo, hi)
uniform uint u_id_base;    // pixel ids of this pass start here (the low-resolution pass: after the frame's)

// Ordered bits of a float: a < b iff key(a) < key(b) (for atomicMin / atomicMax).
uint float_key(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : u | 0x80000000u;
}
float key_float(uint k) {
    return uintBitsToFloat((k & 0x80000000u) != 0u ? k & 0x7FFFFFFFu : ~k);
}
vec3 bounds_lo() { return vec3(key_float(bounds[0]), key_float(bounds[1]), key_float(bounds[2])); }
vec3 bounds_hi() { return vec3(key_float(bounds[3]), key_float(bounds[4]), key_float(bounds[5])); }
