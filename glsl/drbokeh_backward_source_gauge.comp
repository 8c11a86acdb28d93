// Dr.Bokeh backward pass 4, gauge path: the default model with a polygon or ellipse
// aperture (K = 1, the shape's closed-form gauge, mirrored for the side of focus). The disk
// path's code with that gauge; same bindings, push constants and dispatch as
// glsl/drbokeh_backward_source.comp; the body is glsl/common/drbokeh_backward_source.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_BACKWARD_DISK 1
#define DRBOKEH_BACKWARD_GAUGE 1
#include "drbokeh_backward_source.glsl"
