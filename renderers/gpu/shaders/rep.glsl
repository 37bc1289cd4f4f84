// Reprojection of the left LP buffer into the right view (renderers/pipeline.py reproject, seed 001 §5.1):
// per LP pixel of the left buffer its warped LP coordinates, depth and splat target, a depth buffer and the covered
// flags of the right buffer, and the winner of each pixel's depth ties (renderers/gpu/bindings.py FAMILIES["rep"]).
#include "rep_decl_gen.glsl"
#include "flags_decl_gen.glsl"
const float REP_INF = 1.0 / 0.0;
