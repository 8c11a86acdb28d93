// Dr.Bokeh pass 2 of 4 (per layer): dilation of the tile bounds into a window half-width per
// tile, h_T = ceil(reach_T) - 1 with reach_T = max(gather_T, support_U of every tile U whose
// support reaches T). Every source that can reach a pixel of T, and V's gather disk, then lie
// inside the square of half-width h_T around that pixel.
// CPU reference: src/render/drbokeh/bounds.rs `tile_window_cpu`.
//
// Bindings (set 0, std430):
//   0: tile_bounds  readonly  vec2[layer_count * tiles_x * tiles_y]  from drbokeh_tile_bounds
//   1: tile_window  writeonly int[layer_count * tiles_x * tiles_y]   half-width in px
// Push constants: DrBokehPush; reads tiles_x, tiles_y, layer, max_support.
// Dispatch: (ceil(tiles_x * tiles_y / 256), 1, 1), once per layer, after tile_bounds.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 256, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer TileBounds { vec2 tile_bounds[]; };
layout(std430, set = 0, binding = 1) writeonly buffer TileWindow { int tile_window[]; };

float drbokeh_area_lut(int index) {
    return 1.0; // not used by this pass
}

float aperture_kernel_texel(int index) {
    return 0.0; // not used by this pass
}

// Pixel gap along one axis between tiles k apart: 16|k| - 15, or 0 for the same tile.
float tile_gap(int k) {
    return k == 0 ? 0.0 : float(abs(k) * DRBOKEH_TILE - (DRBOKEH_TILE - 1));
}

void main() {
    int tiles = pc.tiles_x * pc.tiles_y;
    int t = int(gl_GlobalInvocationID.x);
    if (t >= tiles) {
        return;
    }
    int tx = t % pc.tiles_x;
    int ty = t / pc.tiles_x;
    int base = pc.layer * tiles;
    // Tiles farther than this cannot be reached by any support in the stack.
    int range = int(ceil(pc.max_support / float(DRBOKEH_TILE))) + 1;
    float reach = tile_bounds[base + t].y;
    for (int uy = max(ty - range, 0); uy <= min(ty + range, pc.tiles_y - 1); ++uy) {
        for (int ux = max(tx - range, 0); ux <= min(tx + range, pc.tiles_x - 1); ++ux) {
            float support = tile_bounds[base + uy * pc.tiles_x + ux].x;
            float gap = max(tile_gap(ux - tx), tile_gap(uy - ty));
            if (gap < support) {
                reach = max(reach, support);
            }
        }
    }
    tile_window[base + t] = max(int(ceil(reach)) - 1, 0);
}
