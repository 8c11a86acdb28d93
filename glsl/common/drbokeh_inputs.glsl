// The bindings the Dr.Bokeh layer pass and backward passes 2 and 4 share, and the lens-table
// accessors that drbokeh.glsl and aperture.glsl declare. Each shader declares binding 2 and
// bindings 5 and up itself. All are read at lane-varying addresses in the tap loops: uniform
// texel buffers (texelFetch), see Slot::Texels in src/vk/pipeline.rs.
//   0: rgba            vec4 per read pixel, premultiplied, layer-major
//   1: disparity       float per read pixel
//   3: area_lut        float[area_count]                  Params::area_lut_f32
//   4: kernel_weights  float[max(1, kernel_size^2)]        Params::kernel_f32
#ifndef LENSBLUR_DRBOKEH_INPUTS_GLSL
#define LENSBLUR_DRBOKEH_INPUTS_GLSL

layout(set = 0, binding = 0) uniform samplerBuffer rgba;
layout(set = 0, binding = 1) uniform samplerBuffer disparity;
layout(set = 0, binding = 3) uniform samplerBuffer area_lut;
layout(set = 0, binding = 4) uniform samplerBuffer kernel_weights;

float drbokeh_area_lut(int index) {
    return texelFetch(area_lut, index).x;
}

float aperture_kernel_texel(int index) {
    return texelFetch(kernel_weights, index).x;
}

#endif
