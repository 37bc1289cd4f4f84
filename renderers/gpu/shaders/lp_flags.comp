// Set flag bit 2 on the LP pixels of a list (the border footprint the CPU marks per gaze).
#include "common.glsl"
#include "marks_decl_gen.glsl"
#include "flags_decl_gen.glsl"

void main() {
    uint i = gid();
    if (i < uint(u_n)) flags[marks[i]] |= 2u;
}
