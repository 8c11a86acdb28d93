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

// Whether this pass folds onto a running composite that the layers in front started, and so
// may leave a pixel of it as it is (the first layer's pass starts it: every pixel written).
bool drbokeh_folding_onto_layers_in_front() {
    return pc.fold != 0 && pc.layer > 0;
}

// Whether the layers in front already hide core pixel p completely (folding only): their
// transmittance is exactly 0 there, so this layer's step adds T v C / W = 0 and keeps T = 0
// whatever it gathers (C, W and V are finite), and its pass may skip the pixel. Exact, not
// a threshold: an opaque front layer's V is exactly 1 inside it (its visibility sum and
// weight add the same terms), so the pixels behind its interior cost nothing.
bool drbokeh_layer_hidden(ivec2 p) {
    return drbokeh_folding_onto_layers_in_front() && layer_vis[drbokeh_core_index(0, p)] == 0.0;
}

// Window of a tile no source of the layer reaches (EMPTY_WINDOW in src/render/drbokeh/bounds.rs,
// default model only): its gathers run zero times.
const int DRBOKEH_EMPTY_WINDOW = -1;

// Whether the layer pass may leave a tile of window `window` unwritten (folding, after the
// first layer, whose pass starts the composite): no source reaches it, so C = W = 0 and V = 0,
// and the composite step adds T 0 = 0 and keeps T. Exact (a stored 0 would only turn a -0 of
// the running composite into +0). A sparse layer (a flat frame's nearer auto-layers cover a
// fifth to a third of the frame's tiles) then costs only the tiles it reaches.
bool drbokeh_layer_adds_nothing(int window) {
    return drbokeh_folding_onto_layers_in_front() && window == DRBOKEH_EMPTY_WINDOW;
}
