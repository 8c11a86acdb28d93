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

// Whether the layers in front already hide core pixel p completely (folding only): their
// transmittance is exactly 0 there, so this layer's step adds T v C / W = 0 and keeps T = 0
// whatever it gathers (C, W and V are finite), and its pass may skip the pixel. Exact, not
// a threshold: an opaque front layer's V is exactly 1 inside it (its visibility sum and
// weight add the same terms), so the pixels behind its interior cost nothing.
bool drbokeh_layer_hidden(ivec2 p) {
    return pc.fold != 0 && pc.layer > 0 && layer_vis[drbokeh_core_index(0, p)] == 0.0;
}
