// Dr.Bokeh layer pass, disk path: the default model with a disk aperture (K = 1, Euclidean
// gauge). Same bindings, push constants and dispatch as glsl/drbokeh_layer.comp, whose header
// explains the optimisations; the body is glsl/common/drbokeh_layer.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_LAYER_DISK 1
#include "drbokeh_layer.glsl"
