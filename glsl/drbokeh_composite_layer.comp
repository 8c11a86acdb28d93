// Dr.Bokeh pass 3, one layer at a time: the front-to-back composite of
// glsl/drbokeh_composite.comp, folded in as each layer's pass completes, so that a tile holds
// one layer's (C, W, V) instead of every layer's. Per core pixel it keeps the running
// premultiplied sum and the transmittance prod_{k<l} (1 - V_k); the arithmetic and its order
// are the composite's, term for term.
// CPU reference: src/render/drbokeh/cpu.rs `composite_pixel`.
//
// Bindings (set 0, std430), all core-local (pc.core = the frame tile):
//   0: layer_cw       readonly  vec4[core pixels]   (C_l.rgb, W_l) of layer pc.layer
//   1: layer_vis      readonly  float[core pixels]  V_l
//   2: result         vec4[core pixels]             premultiplied RGBA so far (written whole at layer 0)
//   3: transmittance  float[core pixels]            prod_{k<=l} (1 - V_k) (written whole at layer 0)
// Push constants: DrBokehPush; reads core, layer, model.
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), after each layer's pass, front
// layer first.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

layout(set = 0, binding = 0) uniform samplerBuffer layer_cw;
layout(set = 0, binding = 1) uniform samplerBuffer layer_vis;
layout(std430, set = 0, binding = 2) buffer Result { vec4 result[]; };
layout(std430, set = 0, binding = 3) buffer Transmittance { float transmittance[]; };

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
    int i = drbokeh_core_index(0, x);
    // The front layer starts the sums: nothing is read of the buffers' earlier contents.
    vec4 outp = pc.layer == 0 ? vec4(0.0) : result[i];
    float t = pc.layer == 0 ? 1.0 : transmittance[i];
    vec4 cw = texelFetch(layer_cw, i);
    float v = texelFetch(layer_vis, i).x;
    if (pc.model == DRBOKEH_MODEL_DRBOKEH) {
        v *= drbokeh_existence_gate(cw.w);
    }
    vec3 colour = cw.w > 0.0 ? cw.xyz / cw.w : vec3(0.0);
    outp.xyz += t * v * colour;
    outp.w += t * v;
    t *= 1.0 - v;
    result[i] = outp;
    transmittance[i] = t;
}
