// Lens-sample selection shared by the ray-based seed renderers (vdslr, multiview).
// Host side: src/render/lens_samples.rs (same hash, same sets).
#ifndef LENSBLUR_SAMPLING_GLSL
#define LENSBLUR_SAMPLING_GLSL

// Wellons' lowbias32 integer hash; `hash32` in lens_samples.rs.
uint hash32(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

// Which of `patterns` precomputed sample sets pixel p uses; `pattern_index` in lens_samples.rs.
uint pattern_index(uvec2 p, uint patterns) {
    return hash32(hash32(p.x ^ 0x5bd1e995u) ^ p.y) % patterns;
}

#endif
