// Set flag bit 2 on the LP pixels of a list (the border footprint the CPU marks per gaze).
#include "common.glsl"
layout(std430, binding = 13) readonly buffer List { int list[]; };
layout(std430, binding = 14) buffer Flags { uint flags[]; };

void main() {
    uint i = gid();
    if (i < uint(u_n)) flags[list[i]] |= 2u;
}
