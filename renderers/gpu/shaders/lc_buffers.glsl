// Storage buffers of the lightcuts passes (generated from the table renderers/gpu/lightcuts.py:BUFFERS) and their
// uniforms (renderers/gpu/bindings.py FAMILIES["lightcuts"]).
#include "lc_buffers_gen.glsl"
#include "lightcuts_decl_gen.glsl"

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
