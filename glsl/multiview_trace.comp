// Multiview synthesis (Lee, Eisemann & Seidel 2009): per pixel, stratified lens samples traced
// front to back through layered height fields (false position), approximate cone tracing on
// mipmapped premultiplied layers, coverage-alpha compositing, culling of unreachable layers.
// CPU reference: src/render/multiview/mod.rs `shade`/`trace`/`intersect` and prepare.rs.
//
// Bindings (set 0):
//   0: pyramid   vec4[layers * pyramid_len]  per layer: the window's mip levels up to the top
//                                            level read, premultiplied RGBA
//   1: heights   float[layers * window area] disparity, empty pixels at the layer's far bound
//   2: occupancy uint[layers * occupancy_words]  per layer a bit plane (bit i % 32 of word
//                                            i / 32): some coverage within reach of pixel i
//   3: bounds    vec4[layers]                (far disparity, near disparity, active, 0)
//   4: levels    uvec4[window levels]        (offset in a layer's pyramid, width, height, 0)
//   5: samples   vec4[patterns * slots]      (u, v, weight, 0), unit disk, aperture coords
//   6: result    vec4[core.z * core.w]
// Push constants: MultiviewPush (src/render/multiview/gpu.rs).
// Dispatch: (ceil(core.z / 8), ceil(core.w / 8), 1).
// Tiled (src/render/tiling.rs): the dispatch covers `core` (x, y, width, height) and stores
// its results core-local. Heights and pyramids cover the tile's `window` (Window in
// src/render/multiview/prepare.rs): the rect its rays reach, whose origin is a multiple of
// 2^(top level read), so window level L starts at frame texel window.xy >> L and holds the
// frame's texels there. Reads clamp to the frame's edges, then index the window. The culling
// masks are the whole frame's.
//
// `precise` keeps ray positions unfused so the texel each height lookup reads matches the CPU.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "image.glsl"
#include "tile.glsl"
#include "sampling.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#include "dispatch.glsl"

// Read at lane-varying addresses: uniform texel buffers (texelFetch), see Slot::Texels in
// src/vk/pipeline.rs.
layout(set = 0, binding = 0) uniform samplerBuffer pyramid;
layout(set = 0, binding = 1) uniform samplerBuffer heights;
layout(std430, set = 0, binding = 2) readonly buffer Occupancy { uint occupancy[]; };
layout(std430, set = 0, binding = 3) readonly buffer Bounds { vec4 bounds[]; };
layout(std430, set = 0, binding = 4) readonly buffer Levels { uvec4 levels[]; };
layout(std430, set = 0, binding = 5) readonly buffer Samples { vec4 samples[]; };
layout(std430, set = 0, binding = 6) writeonly buffer Result { vec4 result[]; };

layout(push_constant) uniform Push {
    int width;
    int height;
    int layers;
    int level_count;
    int slots;
    int patterns;
    int steps;
    int cull;
    int pyramid_len;
    int occupancy_words;
    int pad1;
    int pad2;
    float k;
    float focus;
    float cone;
    float pad3;
    ivec4 core;
    ivec4 window;
} pc;

// Transmittance below which a ray stops (OPAQUE_TRANSMITTANCE).
const float OPAQUE_TRANSMITTANCE = 1.0e-4;

int nearest_pixel(float x, int size) {
    return int(clamp(floor(x + 0.5), 0.0, float(size - 1)));
}

float height_at(int l, vec2 p, vec2 u, float t) {
    precise float rel = t - pc.focus;
    precise float x = p.x + u.x * rel;
    precise float y = p.y + u.y * rel;
    ivec2 pixel = ivec2(nearest_pixel(x, pc.width), nearest_pixel(y, pc.height));
    return texelFetch(heights, l * pc.window.z * pc.window.w + rect_index(pixel, pc.window)).x;
}

float level_for(float diameter) {
    return min(log2(max(diameter, 1.0)), float(pc.level_count - 1));
}

// Texels across mip level `level` of a frame side of `size` pixels: ceil(size / 2^level).
int level_size(int size, int level) {
    return ((size - 1) >> level) + 1;
}

// Texel (x, y) of a level `frame_w x frame_h` in the frame, clamped to it, read from the
// window's copy of the level (`w` texels wide, starting at frame texel `origin`).
vec4 texel(int base, int w, ivec2 origin, int frame_w, int frame_h, float x, float y) {
    int xi = int(clamp(x, 0.0, float(frame_w - 1)));
    int yi = int(clamp(y, 0.0, float(frame_h - 1)));
    return texelFetch(pyramid, base + (yi - origin.y) * w + (xi - origin.x));
}

vec4 bilinear(int l, int level, vec2 pos) {
    uvec4 info = levels[level];
    int w = int(info.y);
    ivec2 origin = pc.window.xy >> level;
    int frame_w = level_size(pc.width, level);
    int frame_h = level_size(pc.height, level);
    float scale = 1.0 / float(1 << level);
    float cx = (pos.x + 0.5) * scale - 0.5;
    float cy = (pos.y + 0.5) * scale - 0.5;
    float x0 = floor(cx);
    float y0 = floor(cy);
    float fx = cx - x0;
    float fy = cy - y0;
    int base = l * pc.pyramid_len + int(info.x);
    vec4 t00 = texel(base, w, origin, frame_w, frame_h, x0, y0);
    vec4 t10 = texel(base, w, origin, frame_w, frame_h, x0 + 1.0, y0);
    vec4 t01 = texel(base, w, origin, frame_w, frame_h, x0, y0 + 1.0);
    vec4 t11 = texel(base, w, origin, frame_w, frame_h, x0 + 1.0, y0 + 1.0);
    vec4 top = t00 + (t10 - t00) * fx;
    vec4 bottom = t01 + (t11 - t01) * fx;
    return top + (bottom - top) * fy;
}

vec4 sample_cone(int l, vec2 pos, float diameter) {
    float level = level_for(diameter);
    float l0 = floor(level);
    float frac = level - l0;
    int i0 = int(l0);
    int i1 = min(i0 + 1, pc.level_count - 1);
    vec4 a = bilinear(l, i0, pos);
    vec4 b = bilinear(l, i1, pos);
    return a + (b - a) * frac;
}

// The culling mask's bit of `pixel` in layer `l` (Prepared::occupied).
uint occupied(int l, int pixel) {
    return (occupancy[l * pc.occupancy_words + (pixel >> 5)] >> uint(pixel & 31)) & 1u;
}

// False position between the layer's far (lo) and near (hi) disparity.
float intersect(int l, vec2 p, vec2 u, float lo, float hi) {
    float ta = hi;
    float fa = height_at(l, p, u, hi) - hi;
    if (fa >= 0.0) {
        return ta;
    }
    float tb = lo;
    float fb = height_at(l, p, u, lo) - lo;
    for (int i = 0; i < pc.steps; ++i) {
        precise float t = ta + (tb - ta) * (fa / (fa - fb));
        float ft = height_at(l, p, u, t) - t;
        if (ft >= 0.0) {
            tb = t;
            fb = ft;
        } else {
            ta = t;
            fa = ft;
        }
    }
    return tb;
}

vec4 trace(vec2 p, vec2 u, int pixel) {
    vec4 acc = vec4(0.0);
    float transmittance = 1.0;
    for (int l = 0; l < pc.layers; ++l) {
        vec4 b = bounds[l];
        if (b.z == 0.0 || (pc.cull != 0 && occupied(l, pixel) == 0u)) {
            continue;
        }
        float t = intersect(l, p, u, b.x, b.y);
        precise float rel = t - pc.focus;
        precise vec2 pos = vec2(p.x + u.x * rel, p.y + u.y * rel);
        vec4 c = sample_cone(l, pos, pc.cone * abs(rel));
        acc += transmittance * c;
        transmittance *= 1.0 - c.a;
        if (transmittance < OPAQUE_TRANSMITTANCE) {
            break;
        }
    }
    return acc;
}

void main() {
    ivec2 local = ivec2(spread_global_invocation_id().xy);
    if (!inside(local, pc.core.zw)) {
        return;
    }
    ivec2 x = pc.core.xy + local;
    int pixel = x.y * pc.width + x.x;
    vec2 p = vec2(x);
    int base = int(pattern_index(uvec2(x), uint(pc.patterns))) * pc.slots;
    vec4 sum = vec4(0.0);
    float weight = 0.0;
    for (int i = 0; i < pc.slots; ++i) {
        vec4 s = samples[base + i];
        if (s.z <= 0.0) {
            continue;
        }
        precise vec2 u = vec2(s.x * pc.k, s.y * pc.k);
        sum += s.z * trace(p, u, pixel);
        weight += s.z;
    }
    result[rect_index(x, pc.core)] = weight > 0.0 ? sum / weight : vec4(0.0);
}
