// Dr.Bokeh backward pass 4, kernel-image path: the default model with a kernel image
// (Euclidean gauge; the kernel's bilinear weight and dK/dr per tap). The disk path's code with
// that weight, without the general shader's other shapes and models, which lavapipe runs
// under lane masks at every tap; same bindings, push constants and dispatch as
// glsl/drbokeh_backward_source.comp; the body is glsl/common/drbokeh_backward_source.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_BACKWARD_DISK 1
#define DRBOKEH_BACKWARD_KERNEL 1
#include "drbokeh_backward_source.glsl"
