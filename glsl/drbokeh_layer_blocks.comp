// Dr.Bokeh pass 2a' (all layers, one dispatch, after glsl/drbokeh_layer_sources.comp): block
// sums of the prepass's (P / A, alpha) along rows, for the disk path's interior spans (there
// every tap adds exactly (P / A, alpha, 1): glsl/common/drbokeh_layer.glsl `span_sum`), and for
// the backward's pass 2 on the disk (alpha). The body and what the sums are:
// glsl/common/drbokeh_blocks.glsl.
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

// Inputs are uniform texel buffers (texelFetch): see Slot::Texels in src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer source_pa;
layout(set = 0, binding = 1) uniform samplerBuffer source_sa;
layout(std430, set = 0, binding = 2) writeonly buffer BlockPrefix { vec4 block_prefix[]; };
layout(std430, set = 0, binding = 3) writeonly buffer BlockSuffix { vec4 block_suffix[]; };
layout(std430, set = 0, binding = 4) writeonly buffer BlockAlpha { vec2 block_alpha[]; };

#define BLOCKS_VALUE(i) texelFetch(source_pa, i)
#define BLOCKS_SCALAR(i) texelFetch(source_sa, i).y
#define BLOCKS_LAYER int(gl_GlobalInvocationID.z)
#include "drbokeh_blocks.glsl"
