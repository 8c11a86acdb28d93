// Single-image scatter baseline (BokehMe's classical renderer), written as a gather so no
// atomics are needed: each output pixel sums, over every source within the largest CoC, the
// weight that source's soft disk gives it, (0.5 + 0.5 tanh(4 (r_y - |x - y|))) / (r_y^2 + 0.2),
// and normalises by the summed weight. The aperture's kernel image (if any), scaled to the
// source's CoC, multiplies the weight.
// CPU reference: src/render/scatter/mod.rs `scatter_pixel` (same taps, same order).
//
// Bindings (set 0):
//   0: source    vec4[read.z * read.w]   premultiplied linear RGBA of the read rect
//   1: disparity float[read.z * read.w]
//   2: result    vec4[core.z * core.w]
//   3: kernel    float[max(1, kernel_size^2)]   aperture kernel image (Aperture::kernel_texels)
// Push constants: ScatterPush (src/render/scatter/gpu.rs).
// Dispatch: (ceil(core.z / 8), ceil(core.w / 8), 1).
// Tiled (src/render/tiling.rs, glsl/common/tile.glsl): the dispatch covers `core`, sources
// are the `read` rect, results core-local; width and height are the full frame's.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "image.glsl"
#include "tile.glsl"
#include "aperture.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "dispatch.glsl"

// Read at lane-varying addresses: uniform texel buffers (texelFetch), see Slot::Texels in
// src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer source;
layout(set = 0, binding = 1) uniform samplerBuffer disparity;
layout(std430, set = 0, binding = 2) writeonly buffer Result { vec4 result[]; };
layout(set = 0, binding = 3) uniform samplerBuffer kernel_weights;

layout(push_constant) uniform Push {
    int width;
    int height;
    int reach;
    int kernel_size;
    float k;
    float focus;
    float edge_sharpness;
    float area_epsilon;
    vec4 aperture;
    ivec4 core;
    ivec4 read;
} pc;

float aperture_kernel_texel(int index) {
    return texelFetch(kernel_weights, index).x;
}

// tanh's argument is clamped to +-9, where f32 tanh is already exactly +-1: some GLSL
// implementations evaluate tanh through exp and return NaN (inf / inf) for large arguments.
float scatter_weight(float r_y, float distance) {
    float t = clamp(pc.edge_sharpness * (r_y - distance), -9.0, 9.0);
    return (0.5 + 0.5 * tanh(t)) / (r_y * r_y + pc.area_epsilon);
}

void main() {
    ivec2 local = ivec2(spread_global_invocation_id().xy);
    if (!inside(local, pc.core.zw)) {
        return;
    }
    ivec2 x = pc.core.xy + local;
    vec4 sum = vec4(0.0);
    float weight = 0.0;
    for (int sy = max(x.y - pc.reach, 0); sy <= min(x.y + pc.reach, pc.height - 1); ++sy) {
        for (int sx = max(x.x - pc.reach, 0); sx <= min(x.x + pc.reach, pc.width - 1); ++sx) {
            int s = rect_index(ivec2(sx, sy), pc.read);
            float rel_y = texelFetch(disparity, s).x - pc.focus;
            vec2 offset = aperture_coords(vec2(float(x.x - sx), float(x.y - sy)), rel_y);
            float r_y = abs(pc.k * rel_y);
            float k = scatter_weight(r_y, aperture_gauge(offset, pc.aperture))
                * aperture_kernel_weight(offset, r_y, pc.aperture, pc.kernel_size);
            sum += k * texelFetch(source, s);
            weight += k;
        }
    }
    // The pixel's own tap weighs at least 0.5 / (r^2 + 0.2) > 0 unless a kernel image blocks
    // it (a ring's obstruction): a pixel no source reaches keeps its own colour.
    result[rect_index(x, pc.core)] = weight > 0.0 ? sum / weight : texelFetch(source, rect_index(x, pc.read));
}
