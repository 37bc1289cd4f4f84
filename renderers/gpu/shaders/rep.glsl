// Reprojection of the left LP buffer into the right view (renderers/pipeline.py reproject, seed 001 §5.1):
// per LP pixel of the left buffer its warped LP coordinates (u, phi), view depth z and splat target; a depth
// buffer of float bits (positive floats order like their bits, so atomicMin is a depth test) and the
// covered flags of the right buffer.
layout(std430, binding = 0) buffer Warp { vec4 warp[]; };      // u, phi, z (INF: miss or behind), target
layout(std430, binding = 1) buffer ZBuf { uint zbuf[]; };
layout(std430, binding = 2) buffer Covered { uint covered[]; };
layout(std430, binding = 3) buffer ZTri { uint ztri[]; };      // nearest warped triangle
// Of the writers whose depth is the minimum at a pixel (a fronto-parallel wall gives many equal float depths),
// the one with the largest id + 1 writes its colour (0: none yet): threads racing to write would leave a
// different colour from run to run. A pixel's writers are all splats or all triangles (rep_splat.comp).
layout(std430, binding = 15) buffer Winner { uint winner[]; };
uniform float u_splat_margin;
layout(std430, binding = 14) buffer Flags { uint flags[]; };   // bit 0: shaded in the left eye (= needed)
const float REP_INF = 1.0 / 0.0;
