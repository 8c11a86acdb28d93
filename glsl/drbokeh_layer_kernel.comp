// Dr.Bokeh layer pass, kernel-image path: the default model with an `image:` aperture, every
// tap evaluated as in glsl/drbokeh_layer.comp but without the compat model's terms and the
// other shapes' gauges, which lavapipe would run under lane masks at every tap. Same bindings,
// push constants and dispatch as glsl/drbokeh_layer.comp; the body is
// glsl/common/drbokeh_layer.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_LAYER_KERNEL 1
#include "drbokeh_layer.glsl"
