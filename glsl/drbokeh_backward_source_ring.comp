// Dr.Bokeh backward pass 4, ring path: the default model with the ring aperture (Euclidean
// gauge, the ring's weight and dK/dr in closed form). The disk path's code with that weight;
// same bindings, push constants and dispatch as glsl/drbokeh_backward_source.comp; the body
// is glsl/common/drbokeh_backward_source.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_BACKWARD_DISK 1
#define DRBOKEH_BACKWARD_RING 1
#include "drbokeh_backward_source.glsl"
