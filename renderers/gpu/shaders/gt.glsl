// GT sample positions (renderers/pipeline.py gt_sample_offsets): SPP samples per pixel on a
// SPP_SIDE x SPP_SIDE grid of strata, each jittered inside its stratum by an integer hash of (pixel, sample)
// (Wellons' lowbias32; constants HASH_* from pipeline.py); one sample at the pixel centre when SPP is 1.
uint lowbias32(uint x) {
    x ^= x >> 16; x *= HASH_M1; x ^= x >> 15; x *= HASH_M2; x ^= x >> 16;
    return x;
}
vec2 gt_offset(int px, int py, int s) {
    if (SPP == 1) return vec2(0.5);
    uint h = lowbias32((uint(px) * HASH_X) ^ lowbias32(uint(py) ^ lowbias32(uint(s))));
    uint h2 = lowbias32(h ^ HASH_Y);
    vec2 jit = vec2(float(h >> 8u), float(h2 >> 8u)) * (1.0 / 16777216.0);
    return (vec2(float(s % SPP_SIDE), float(s / SPP_SIDE)) + jit) / float(SPP_SIDE);
}
