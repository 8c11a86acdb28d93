// Dr.Bokeh layer pass, gauge path: the default model with a polygon or ellipse aperture (K = 1,
// the shape's gauge, mirrored for near sources). The disk path's row spans with per-row bounds
// from the aperture's row table (binding 13, src/camera/aperture_rows.rs): the shape is convex,
// so each row of its interior and of its reach is one interval. Otherwise the bindings, push
// constants and dispatch of glsl/drbokeh_layer.comp; the body is glsl/common/drbokeh_layer.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_LAYER_GAUGE 1
#include "drbokeh_layer.glsl"
