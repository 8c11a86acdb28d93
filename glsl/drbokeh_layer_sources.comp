// Dr.Bokeh pass 2a (all layers, one dispatch): the per-source terms of the layer gathers,
// computed once per source instead of once per tap (a source is read by ~pi r^2 centres).
//   source_pa = P(y) / A(r_y)   (premultiplied RGBA over the area normalisation; exactly 0
//                                when alpha <= 0, so such sources add nothing to C and W)
//   source_sa = (s_y, alpha_y)  (signed CoC radius in px, raw alpha for the visibility V)
// Read by glsl/drbokeh_layer.comp; CPU terms: src/render/drbokeh/cpu.rs `layer_pixel`.
//
// Bindings (set 0, std430), over the uploaded rect pc.read, layer-major like the sources:
//   0: rgba       readonly  vec4[layer_count * read pixels]
//   1: disparity  readonly  float[layer_count * read pixels]
//   2: area_lut   readonly  float[area_count] (x 17 levels for a vignetted lens)
//   3: source_pa  writeonly vec4[layer_count * read pixels]
//   4: source_sa  writeonly vec2[layer_count * read pixels]
// Dispatch: (ceil(read width / 16), ceil(read height / 16), layer_count).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

// Whether the lens is vignetted (shape -2, default model only: each source normalised by its
// own position's shape, drbokeh_area_at). A specialization constant, not the push constant's
// shape: the vignetted polygon's and ellipse's direction and four tables, even never run,
// slowed every other lens's prepass by ~40% on lavapipe (195 -> 280 ms, 1024^2 frame).
layout(constant_id = 0) const bool SOURCES_VIGNETTED = false;

// Inputs are uniform texel buffers (texelFetch): see Slot::Texels in src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer rgba;
layout(set = 0, binding = 1) uniform samplerBuffer disparity;
layout(set = 0, binding = 2) uniform samplerBuffer area_lut;
layout(std430, set = 0, binding = 3) writeonly buffer SourcePa { vec4 source_pa[]; };
layout(std430, set = 0, binding = 4) writeonly buffer SourceSa { vec2 source_sa[]; };

float drbokeh_area_lut(int index) {
    return texelFetch(area_lut, index).x;
}

// Never called here (no lens term); GLSL needs a body for the declaration in aperture.glsl.
float aperture_kernel_texel(int index) {
    return 0.0;
}

void main() {
    ivec2 local = ivec2(gl_GlobalInvocationID.xy);
    int layer = int(gl_GlobalInvocationID.z);
    if (local.x >= pc.read.z || local.y >= pc.read.w || layer >= pc.layer_count) {
        return;
    }
    int i = drbokeh_read_index(layer, pc.read.xy + local);
    vec4 p = texelFetch(rgba, i);
    float s = pc.k_px * (texelFetch(disparity, i).x - pc.focus_disparity);
    ivec2 position = pc.read.xy + local;
    float area = SOURCES_VIGNETTED ? drbokeh_area_at(abs(s), position) : drbokeh_area_for(abs(s));
    source_pa[i] = p.w > 0.0 ? p / area : vec4(0.0);
    source_sa[i] = vec2(s, p.w);
}
