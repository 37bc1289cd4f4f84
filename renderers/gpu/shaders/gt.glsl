// GT sample positions (renderers/pipeline.py gt_sample_offsets): SPP samples per pixel on a
// SPP_SIDE x SPP_SIDE grid of strata, each jittered inside its stratum by an integer hash of (pixel, sample)
// (Wellons' lowbias32; constants HASH_* from pipeline.py); one sample at the pixel centre when SPP is 1.
uint lowbias32(uint x) {
    x ^= x >> 16; x *= HASH_M1; x ^= x >> 15; x *= HASH_M2; x ^= x >> 16;
    return x;
}
dvec2 gt_offset(int px, int py, int s) {   // float64, as the CPU computes it
    if (SPP == 1) return dvec2(0.5LF);
    uint h = lowbias32((uint(px) * HASH_X) ^ lowbias32(uint(py) ^ lowbias32(uint(s))));
    uint h2 = lowbias32(h ^ HASH_Y);
    dvec2 jit = dvec2(double(h >> 8u), double(h2 >> 8u)) / 16777216.0LF;
    return (dvec2(double(s % SPP_SIDE), double(s / SPP_SIDE)) + jit) / double(SPP_SIDE);
}
