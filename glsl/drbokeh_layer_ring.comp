// Dr.Bokeh layer pass, ring path: the default model with the ring aperture (a disk less a
// central obstruction; Euclidean gauge, the ring weight of src/camera/aperture.rs). The disk
// path's gather, then a second one over the obstruction (a disk of radius inner r inside the
// rim) whose terms are subtracted, both with row spans and interior sums. Same bindings, push
// constants and dispatch as glsl/drbokeh_layer.comp; the body is glsl/common/drbokeh_layer.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_LAYER_RING 1
#include "drbokeh_layer.glsl"
