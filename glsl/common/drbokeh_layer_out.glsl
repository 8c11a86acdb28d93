// The outputs of a layer pass (bindings 5 and 6) and how it writes them, shared by
// drbokeh_layer.glsl (the optimised kernels) and drbokeh_layer_naive.comp. Include after
// drbokeh.glsl (push constants, drbokeh_composite_step).
// (C, W) and V of the layer, or (`pc.fold`) the running composite and its transmittance.
layout(std430, set = 0, binding = 5) buffer LayerCw { vec4 layer_cw[]; };
layout(std430, set = 0, binding = 6) buffer LayerVis { float layer_vis[]; };

// The layer pass's result at a core pixel: stored, or folded into the running composite.
void drbokeh_layer_out(int i, vec4 cw, float v) {
    if (pc.fold == 0) {
        layer_cw[i] = cw;
        layer_vis[i] = v;
        return;
    }
    vec4 outp = pc.layer == 0 ? vec4(0.0) : layer_cw[i];
    float transmittance = pc.layer == 0 ? 1.0 : layer_vis[i];
    drbokeh_composite_step(outp, transmittance, cw, v);
    layer_cw[i] = outp;
    layer_vis[i] = transmittance;
}
