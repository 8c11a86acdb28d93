// Single-image gather baseline (Blender Defocus-like): each output pixel averages the
// neighbours inside min(own CoC, neighbour's CoC), with a 1 px anti-aliased rim, weighted by
// the aperture's kernel image (if any) scaled to its own CoC.
// CPU reference: src/render/gather/mod.rs `gather_pixel` (same taps, same order).
//
// Bindings (set 0):
//   0: source    vec4[read.z * read.w]   premultiplied linear RGBA of the read rect
//   1: disparity float[read.z * read.w]
//   2: result    vec4[core.z * core.w]
//   3: kernel    float[max(1, kernel_size^2)]   aperture kernel image (Aperture::kernel_texels)
// Push constants: GatherPush (src/render/gather/gpu.rs).
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
    float k;
    float focus;
    float edge_width;
    int kernel_size;
    float pad1;
    float pad2;
    vec4 aperture;
    ivec4 core;
    ivec4 read;
} pc;

float aperture_kernel_texel(int index) {
    return texelFetch(kernel_weights, index).x;
}

float coc_radius(float d) {
    return abs(pc.k * (d - pc.focus));
}

void main() {
    ivec2 local = ivec2(spread_global_invocation_id().xy);
    if (!inside(local, pc.core.zw)) {
        return;
    }
    ivec2 x = pc.core.xy + local;
    int centre = rect_index(x, pc.read);
    float r_x = coc_radius(texelFetch(disparity, centre).x);
    float rel_x = texelFetch(disparity, centre).x - pc.focus;
    int reach = int(ceil(r_x + 0.5 * pc.edge_width));
    vec4 sum = vec4(0.0);
    float weight = 0.0;
    for (int sy = max(x.y - reach, 0); sy <= min(x.y + reach, pc.height - 1); ++sy) {
        for (int sx = max(x.x - reach, 0); sx <= min(x.x + reach, pc.width - 1); ++sx) {
            int s = rect_index(ivec2(sx, sy), pc.read);
            vec2 offset = aperture_coords(vec2(float(x.x - sx), float(x.y - sy)), rel_x);
            float distance = aperture_gauge(offset, pc.aperture);
            float reach_both = min(r_x, coc_radius(texelFetch(disparity, s).x));
            float k = clamp((reach_both - distance) / pc.edge_width + 0.5, 0.0, 1.0);
            if (k > 0.0) {
                k *= aperture_kernel_weight(offset, r_x, pc.aperture, pc.kernel_size);
            }
            if (k > 0.0) {
                sum += k * texelFetch(source, s);
                weight += k;
            }
        }
    }
    // The centre tap has k >= 0.5, but a kernel image can block it (a ring's obstruction): a
    // pixel no tap reaches through the aperture keeps its own colour.
    result[rect_index(x, pc.core)] = weight > 0.0 ? sum / weight : texelFetch(source, centre);
}
