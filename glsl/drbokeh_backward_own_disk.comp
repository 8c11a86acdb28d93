// Dr.Bokeh backward pass 2, disk path: the default model with a disk aperture and no kernel
// image (K = 1, Euclidean gauge). The bindings, push constants and dispatch of
// glsl/drbokeh_backward_own.comp, plus
//   9: block_alpha  readonly  vec2[layer_count * read pixels]  the forward's alpha block sums
//                   (glsl/drbokeh_layer_blocks.comp), for V's interior rows
// The body is glsl/common/drbokeh_backward_own.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_BACKWARD_DISK 1
#define DRBOKEH_BACKWARD_SPANS 1
#include "drbokeh_backward_own.glsl"
