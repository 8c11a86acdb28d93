// Dr.Bokeh backward pass 4, disk path: the default model with a disk aperture and no kernel
// image (K = 1, Euclidean gauge). Same bindings, push constants and dispatch as
// glsl/drbokeh_backward_source.comp; the body is glsl/common/drbokeh_backward_source.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_BACKWARD_DISK 1
#include "drbokeh_backward_source.glsl"
