// Dr.Bokeh backward pass 1 of 4: reverse of drbokeh_composite.comp. Per pixel and layer,
// dL/d(C_l.rgb, W_l) and dL/dV_l from dL/d(output). With G_l = gout . (C_l / W_l, 1) and
// acc_l = v_l G_l + (1 - v_l) acc_{l+1}, dL/dv_l = T_l (G_l - acc_{l+1}) (no division by
// 1 - v). T_l is recomputed per layer (O(layers^2) reads of V: no fixed-size arrays).
// CPU reference: src/render/drbokeh/backward_cpu.rs `composite_pixel`.
//
// Bindings (set 0, std430): "core" = pc.core, the receivers of this frame tile (the forward's
// core); "read" = pc.read, the uploaded sources (the adjoints are stored read-local so that
// pass 4, whose core is the tile's sources, indexes them like the sources):
//   0: layer_cw     readonly  vec4[layer_count * core pixels]  (C_l.rgb, W_l)
//   1: layer_vis    readonly  float[layer_count * core pixels] V_l
//   2: grad_output  readonly  vec4[core pixels]                dL/d(output RGBA)
//   3: adj_cw       writeonly vec4[layer_count * read pixels]  dL/d(C_l.rgb, W_l)
//   4: adj_vis      writeonly float[layer_count * read pixels] dL/dV_l
// Push constants: DrBokehPush; reads core, read, layer_count, model.
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once, after the forward passes.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh_grad.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer LayerCw { vec4 layer_cw[]; };
layout(std430, set = 0, binding = 1) readonly buffer LayerVis { float layer_vis[]; };
layout(std430, set = 0, binding = 2) readonly buffer GradOutput { vec4 grad_output[]; };
layout(std430, set = 0, binding = 3) writeonly buffer AdjCw { vec4 adj_cw[]; };
layout(std430, set = 0, binding = 4) writeonly buffer AdjVis { float adj_vis[]; };

float drbokeh_area_lut(int index) {
    return 1.0; // not used by this pass
}

float aperture_kernel_texel(int index) {
    return 0.0; // not used by this pass
}

// The existence-gated visibility v_l the forward composites with.
float gated_visibility(int l, ivec2 x) {
    int at = drbokeh_core_index(l, x);
    float v = layer_vis[at];
    return pc.model == DRBOKEH_MODEL_DRBOKEH ? v * drbokeh_existence_gate(layer_cw[at].w) : v;
}

void main() {
    ivec2 x = drbokeh_core_pixel(gl_GlobalInvocationID);
    if (x.x < 0) {
        return;
    }
    vec4 gout = grad_output[drbokeh_core_index(0, x)];
    float acc = 0.0;
    for (int l = pc.layer_count - 1; l >= 0; --l) {
        float t = 1.0;
        for (int k = 0; k < l; ++k) {
            t *= 1.0 - gated_visibility(k, x);
        }
        vec4 cw = layer_cw[drbokeh_core_index(l, x)];
        float vis = layer_vis[drbokeh_core_index(l, x)];
        float gate = pc.model == DRBOKEH_MODEL_DRBOKEH ? drbokeh_existence_gate(cw.w) : 1.0;
        float v = vis * gate;
        vec3 colour = cw.w > 0.0 ? cw.xyz / cw.w : vec3(0.0);
        float g = dot(gout.xyz, colour) + gout.w;
        float d_v = t * (g - acc);
        acc = v * g + (1.0 - v) * acc;
        vec4 d_cw = vec4(0.0);
        if (cw.w > 0.0) {
            vec3 d_colour = t * v * gout.xyz;
            d_cw = vec4(d_colour / cw.w, -dot(d_colour, colour) / cw.w);
        }
        float d_vis = d_v;
        if (pc.model == DRBOKEH_MODEL_DRBOKEH) {
            d_cw.w += d_v * vis * drbokeh_d_existence_gate(cw.w);
            d_vis = d_v * gate;
        }
        adj_cw[drbokeh_read_index(l, x)] = d_cw;
        adj_vis[drbokeh_read_index(l, x)] = d_vis;
    }
}
