// Dr.Bokeh pass 2a' (all layers, one dispatch, after glsl/drbokeh_layer_sources.comp): block
// sums of the prepass's (P / A, alpha) along rows, for the disk path's interior spans (there
// every tap adds exactly (P / A, alpha, 1): glsl/common/drbokeh_layer.glsl `span_sum`).
// Blocks are the search tiles' DRBOKEH_TILE columns, aligned to GLOBAL x, so every
// sum is a function of global pixel positions only: the output stays bit-identical whatever
// the frame tile (and so the read rect) is. Per source x in block [b0, b1]:
//   block_prefix = sum of columns b0 .. x, added left to right (b0 first)
//   block_suffix = sum of columns x .. b1, added right to left (b1 first)
// (vec4 P / A, and alpha in block_alpha = (prefix, suffix)). The block total is block_suffix
// at b0. A block cut by the read rect's edge gets partial sums here; the layer pass never
// reads them (a span's suffix part lies right of its start >= read.x, its prefix part left
// of its end < read.x + read.z, and its whole blocks between both).
//
// Bindings (set 0, std430), over the uploaded rect pc.read, layer-major like the sources:
//   0: source_pa     readonly  vec4[layer_count * read pixels]
//   1: source_sa     readonly  vec2[layer_count * read pixels]
//   2: block_prefix  writeonly vec4[layer_count * read pixels]
//   3: block_suffix  writeonly vec4[layer_count * read pixels]
//   4: block_alpha   writeonly vec2[layer_count * read pixels]
// Dispatch: (ceil(blocks per read row / 16), ceil(read height / 16), layer_count), one
// invocation per block and row; blocks per read row = (read.x + read.z - 1) / DRBOKEH_TILE
// - read.x / DRBOKEH_TILE + 1.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

// Inputs are uniform texel buffers (texelFetch): see Slot::Texels in src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer source_pa;
layout(set = 0, binding = 1) uniform samplerBuffer source_sa;
layout(std430, set = 0, binding = 2) writeonly buffer BlockPrefix { vec4 block_prefix[]; };
layout(std430, set = 0, binding = 3) writeonly buffer BlockSuffix { vec4 block_suffix[]; };
layout(std430, set = 0, binding = 4) writeonly buffer BlockAlpha { vec2 block_alpha[]; };

float drbokeh_area_lut(int index) {
    return 0.0;
}

float aperture_kernel_texel(int index) {
    return 0.0;
}

void main() {
    int block = pc.read.x / DRBOKEH_TILE + int(gl_GlobalInvocationID.x);
    int y = int(gl_GlobalInvocationID.y);
    int layer = int(gl_GlobalInvocationID.z);
    int read_x1 = pc.read.x + pc.read.z - 1;
    if (block * DRBOKEH_TILE > read_x1 || y >= pc.read.w || layer >= pc.layer_count) {
        return;
    }
    // The block's columns inside the read rect (global x).
    int x0 = max(block * DRBOKEH_TILE, pc.read.x);
    int x1 = min(block * DRBOKEH_TILE + DRBOKEH_TILE - 1, read_x1);
    int row = drbokeh_read_index(layer, ivec2(pc.read.x, pc.read.y + y)) - pc.read.x;
    vec4 pa = vec4(0.0);
    float alpha = 0.0;
    for (int x = x0; x <= x1; ++x) {
        pa += texelFetch(source_pa, row + x);
        alpha += texelFetch(source_sa, row + x).y;
        block_prefix[row + x] = pa;
        block_alpha[row + x].x = alpha;
    }
    pa = vec4(0.0);
    alpha = 0.0;
    for (int x = x1; x >= x0; --x) {
        pa += texelFetch(source_pa, row + x);
        alpha += texelFetch(source_sa, row + x).y;
        block_suffix[row + x] = pa;
        block_alpha[row + x].y = alpha;
    }
}
