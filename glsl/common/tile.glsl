// Frame tiles (src/render/tiling.rs): a dispatch covers one tile's core; its sources are the
// uploaded read rect (core + halo, clipped to the frame) and its results are stored
// core-local. Positions stay in frame pixels, clamped to the full frame, so a tile computes
// exactly what the whole frame computes there. Rects are (x, y, width, height).
#ifndef LENSBLUR_TILE_GLSL
#define LENSBLUR_TILE_GLSL

// Index of frame pixel p in a buffer holding `rect` row-major.
int rect_index(ivec2 p, ivec4 rect) {
    return (p.y - rect.y) * rect.z + (p.x - rect.x);
}

#endif
