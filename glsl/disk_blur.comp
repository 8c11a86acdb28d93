// Constant-radius disk convolution of an RGBA image with edge renormalisation.
// CPU reference: src/render/disk.rs `disk_blur_cpu` (same taps, same order).
//
// Bindings (set 0):
//   0: source  vec4[width * height]   premultiplied linear RGBA
//   1: kernel  float[side * side]     anti-aliased disk weights, side = 2 * half_extent + 1
//   2: result  vec4[width * height]
// Push constants: DiskBlurPush { width, height, half_extent, pad }.
// Dispatch: (ceil(width / 16), ceil(height / 16), 1).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "image.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

// Read at lane-varying addresses: uniform texel buffers (texelFetch), see Slot::Texels in
// src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer source;
layout(set = 0, binding = 1) uniform samplerBuffer kernel_weights;
layout(std430, set = 0, binding = 2) writeonly buffer Result { vec4 result[]; };

layout(push_constant) uniform Push {
    int width;
    int height;
    int half_extent;
    int pad;
} pc;

void main() {
    ivec2 size = ivec2(pc.width, pc.height);
    ivec2 x = ivec2(gl_GlobalInvocationID.xy);
    if (!inside(x, size)) {
        return;
    }
    int side = 2 * pc.half_extent + 1;
    vec4 sum = vec4(0.0);
    float weight = 0.0;
    for (int ky = 0; ky < side; ++ky) {
        int sy = x.y + ky - pc.half_extent;
        if (sy < 0 || sy >= size.y) {
            continue;
        }
        for (int kx = 0; kx < side; ++kx) {
            int sx = x.x + kx - pc.half_extent;
            float k = texelFetch(kernel_weights, ky * side + kx).x;
            if (sx < 0 || sx >= size.x || k == 0.0) {
                continue;
            }
            sum += k * texelFetch(source, sy * size.x + sx);
            weight += k;
        }
    }
    result[x.y * size.x + x.x] = weight > 0.0 ? sum / weight : vec4(0.0);
}
