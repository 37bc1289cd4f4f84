// Reprojection of the left LP buffer into the right view (renderers/pipeline.py reproject, seed 001 §5.1):
// per LP pixel of the left buffer its warped LP coordinates (u, phi), view depth z and splat target; a depth
// buffer of float bits (positive floats order like their bits, so atomicMin is a depth test) and the
// covered flags of the right buffer (renderers/gpu/bindings.py FAMILIES["rep"]). Of the writers whose depth is
// the minimum at a pixel (a fronto-parallel wall gives many equal float depths), the one with the largest id + 1
// writes its colour (winner): a pixel's writers are all splats or all triangles (rep_splat.comp).
#include "rep_decl_gen.glsl"
#include "flags_decl_gen.glsl"
const float REP_INF = 1.0 / 0.0;
