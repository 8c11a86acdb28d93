// Dr.Bokeh backward pass 3' (per layer, after pass 2 of that layer, before its pass 4): block
// sums along rows of the receivers' colour adjoints (pass 1's adj_cw) and of their normalised
// V adjoints (pass 2's receiver.z = dL/dV / sum D), for pass 4's interior spans on the disk
// (there every receiver adds exactly its adjoints: glsl/common/drbokeh_backward_source.glsl).
// They are written over the layer's part of the forward's block sums, which pass 2 of this
// layer has read and nothing reads after it. The body and what the sums are:
// glsl/common/drbokeh_blocks.glsl.
//
// Bindings (set 0, std430), over the uploaded rect pc.read, layer-major:
//   0: adj_cw        readonly  vec4[layer_count * read pixels]
//   1: receiver      readonly  vec4[layer_count * read pixels]  (rel_x, alpha_x, V / sum D, h_x)
//   2: block_prefix  writeonly vec4[layer_count * read pixels]  sums of adj_cw
//   3: block_suffix  writeonly vec4[layer_count * read pixels]
//   4: block_alpha   writeonly vec2[layer_count * read pixels]  sums of receiver.z
// Dispatch: (ceil(blocks per read row / 16), ceil(read height / 16), 1) for layer pc.layer.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(set = 0, binding = 0) uniform samplerBuffer adj_cw;
layout(set = 0, binding = 1) uniform samplerBuffer receiver;
layout(std430, set = 0, binding = 2) writeonly buffer BlockPrefix { vec4 block_prefix[]; };
layout(std430, set = 0, binding = 3) writeonly buffer BlockSuffix { vec4 block_suffix[]; };
layout(std430, set = 0, binding = 4) writeonly buffer BlockAlpha { vec2 block_alpha[]; };

#define BLOCKS_VALUE(i) texelFetch(adj_cw, i)
#define BLOCKS_SCALAR(i) texelFetch(receiver, i).z
#define BLOCKS_LAYER pc.layer
#include "drbokeh_blocks.glsl"
