// Dr.Bokeh backward pass 4, disk path: the default model with a disk aperture and no kernel
// image (K = 1, Euclidean gauge). The bindings, push constants and dispatch of
// glsl/drbokeh_backward_source.comp, plus, for the interior spans (after pass 3' of the layer,
// glsl/drbokeh_backward_blocks.comp):
//  11: block_prefix     readonly  vec4[layer_count * read pixels]  block sums of adj_cw
//  12: block_suffix     readonly  vec4[layer_count * read pixels]
//  13: block_alpha      readonly  vec2[layer_count * read pixels]  block sums of receiver.z
//  14: receiver_radius  readonly  float[layer_count * tiles_x * tiles_y] whole image: the
//                       smallest |s| of a receiver within the tile's reach (host:
//                       bounds.rs `receiver_radii`)
// The body is glsl/common/drbokeh_backward_source.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_BACKWARD_DISK 1
#define DRBOKEH_BACKWARD_SPANS 1
#include "drbokeh_backward_source.glsl"
