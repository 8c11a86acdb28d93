// Dr.Bokeh backward pass 3 of 4 (per layer): the transpose of the tile windows. A source
// in tile T lies in the window of a receiver in tile U only if the pixel gap between the
// tiles is at most h_U, so reach_T = max { h_U : gap(U, T) <= h_U } bounds the square of
// receivers pass 4 visits (it includes h_T itself).
// CPU reference: src/render/drbokeh/backward_cpu.rs `tile_reach_cpu`.
//
// Bindings (set 0, std430):
//   0: tile_window  readonly  int[layer_count * tiles_x * tiles_y]  from drbokeh_tile_window
//   1: tile_reach   writeonly int[layer_count * tiles_x * tiles_y]  half-width in px
// Push constants: DrBokehPush; reads tiles_x, tiles_y, layer, max_support.
// Dispatch: (ceil(tiles_x * tiles_y / 256), 1, 1), once per layer, after the forward passes.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 256, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer TileWindow { int tile_window[]; };
layout(std430, set = 0, binding = 1) writeonly buffer TileReach { int tile_reach[]; };

float drbokeh_area_lut(int index) {
    return 1.0; // not used by this pass
}

float aperture_kernel_texel(int index) {
    return 0.0; // not used by this pass
}

// Pixel gap along one axis between tiles k apart: 16|k| - 15, or 0 for the same tile.
int tile_gap(int k) {
    return k == 0 ? 0 : abs(k) * DRBOKEH_TILE - (DRBOKEH_TILE - 1);
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
    // Windows are at most ceil(max_support) - 1 px: tiles farther apart never see each other.
    int range = int(ceil(pc.max_support / float(DRBOKEH_TILE))) + 1;
    int reach = 0;
    for (int uy = max(ty - range, 0); uy <= min(ty + range, pc.tiles_y - 1); ++uy) {
        for (int ux = max(tx - range, 0); ux <= min(tx + range, pc.tiles_x - 1); ++ux) {
            int h = tile_window[base + uy * pc.tiles_x + ux];
            if (max(tile_gap(ux - tx), tile_gap(uy - ty)) <= h) {
                reach = max(reach, h);
            }
        }
    }
    tile_reach[base + t] = reach;
}
