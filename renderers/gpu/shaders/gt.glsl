// GT sample positions (renderers/pipeline.py gt_sample_offsets): gt_sample_offset, generated from pipeline.py
// sample_offset (SPP samples per pixel, SPP_SIDE x SPP_SIDE strata); one sample at the pixel centre when SPP is 1.
#include "gt_gen.glsl"
dvec2 gt_offset(int px, int py, int s) { return SPP == 1 ? dvec2(0.5LF) : gt_sample_offset(px, py, s, SPP_SIDE); }
