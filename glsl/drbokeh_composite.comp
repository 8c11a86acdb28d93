// Dr.Bokeh pass 3 of 3: front-to-back composite
// B = sum_l V_l prod_{k<l} (1 - V_k) C_l / W_l, alpha = sum_l V_l prod_{k<l} (1 - V_k);
// the default model gates V_l by the layer's existence (W_l > 0). Premultiplied, unclamped.
// CPU reference: src/render/drbokeh/cpu.rs `composite_pixel`.
//
// Bindings (set 0, std430), all core-local (pc.core = the frame tile):
//   0: layer_cw   readonly  vec4[layer_count * core pixels]  (C_l.rgb, W_l)
//   1: layer_vis  readonly  float[layer_count * core pixels] V_l
//   2: result     writeonly vec4[core pixels]                premultiplied RGBA
// Push constants: DrBokehPush; reads core, layer_count, model.
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once, after every layer pass.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

// Read at lane-varying addresses: uniform texel buffers (texelFetch), see Slot::Texels in
// src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer layer_cw;
layout(set = 0, binding = 1) uniform samplerBuffer layer_vis;
layout(std430, set = 0, binding = 2) writeonly buffer Result { vec4 result[]; };

float drbokeh_area_lut(int index) {
    return 1.0; // not used by this pass
}

float aperture_kernel_texel(int index) {
    return 0.0; // not used by this pass
}

void main() {
    ivec2 x = drbokeh_core_pixel(gl_GlobalInvocationID);
    if (x.x < 0) {
        return;
    }
    vec4 outp = vec4(0.0);
    float transmittance = 1.0;
    for (int l = 0; l < pc.layer_count; ++l) {
        vec4 cw = texelFetch(layer_cw, drbokeh_core_index(l, x));
        float v = texelFetch(layer_vis, drbokeh_core_index(l, x)).x;
        drbokeh_composite_step(outp, transmittance, cw, v);
    }
    result[drbokeh_core_index(0, x)] = outp;
}
