// Dr.Bokeh layer pass, kernel-image path: the default model with an `image:` aperture on the
// disk path's row spans, each row split into the kernel's runs (binding 13, kernel_run_table in
// src/camera/kernel_runs.rs): full-weight runs from the block sums, zero-weight runs skipped,
// the kernel sampled at the taps between. Otherwise the bindings, push constants and dispatch
// of glsl/drbokeh_layer.comp; the body is glsl/common/drbokeh_layer.glsl.
#version 450
#extension GL_GOOGLE_include_directive : require
#define DRBOKEH_LAYER_KERNEL 1
#include "drbokeh_layer.glsl"
