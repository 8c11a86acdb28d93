// Body of the row block sums along global 16-px blocks: glsl/drbokeh_layer_blocks.comp (the
// forward's P / A and alpha) and glsl/drbokeh_backward_blocks.comp (the backward's receiver
// adjoints), which define, before including it:
//   BLOCKS_VALUE(i)   the vec4 summed at read index i, into block_prefix and block_suffix
//   BLOCKS_SCALAR(i)  the float summed at read index i, into block_alpha (prefix, suffix)
//   BLOCKS_LAYER      the layer this invocation sums
// Blocks are the search tiles' DRBOKEH_TILE columns, aligned to GLOBAL x, so every sum is a
// function of global pixel positions only: whatever reads them stays bit-identical whatever
// the frame tile (and so the read rect) is. Per pixel x in block [b0, b1]:
//   block_prefix = sum of columns b0 .. x, added left to right (b0 first)
//   block_suffix = sum of columns x .. b1, added right to left (b1 first)
// (the scalar's in block_alpha = (prefix, suffix)). The block total is block_suffix at b0. A
// block cut by the read rect's edge gets partial sums here; the span sums never read them
// (glsl/common/spans.glsl: a span's suffix part lies right of its start >= read.x, its prefix
// part left of its end < read.x + read.z, and its whole blocks between both).
// One invocation per block and row of the read rect pc.read.
#ifndef LENSBLUR_DRBOKEH_BLOCKS_GLSL
#define LENSBLUR_DRBOKEH_BLOCKS_GLSL

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

// The sums read no lens table.
float drbokeh_area_lut(int index) {
    return 0.0;
}

float aperture_kernel_texel(int index) {
    return 0.0;
}

void main() {
    int block = pc.read.x / DRBOKEH_TILE + int(gl_GlobalInvocationID.x);
    int y = int(gl_GlobalInvocationID.y);
    int layer = BLOCKS_LAYER;
    int read_x1 = pc.read.x + pc.read.z - 1;
    if (block * DRBOKEH_TILE > read_x1 || y >= pc.read.w || layer >= pc.layer_count) {
        return;
    }
    // The block's columns inside the read rect (global x).
    int x0 = max(block * DRBOKEH_TILE, pc.read.x);
    int x1 = min(block * DRBOKEH_TILE + DRBOKEH_TILE - 1, read_x1);
    int row = drbokeh_read_index(layer, ivec2(pc.read.x, pc.read.y + y)) - pc.read.x;
    vec4 value = vec4(0.0);
    float scalar = 0.0;
    for (int x = x0; x <= x1; ++x) {
        value += BLOCKS_VALUE(row + x);
        scalar += BLOCKS_SCALAR(row + x);
        block_prefix[row + x] = value;
        block_alpha[row + x].x = scalar;
    }
    value = vec4(0.0);
    scalar = 0.0;
    for (int x = x1; x >= x0; --x) {
        value += BLOCKS_VALUE(row + x);
        scalar += BLOCKS_SCALAR(row + x);
        block_suffix[row + x] = value;
        block_alpha[row + x].y = scalar;
    }
}

#endif
