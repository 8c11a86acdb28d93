// Dr.Bokeh pass 1 of 4 (per layer): per 16x16 tile, the largest scatter support of a source
// with alpha > 0 and the largest gather radius r + 1/2 of any pixel (V is evaluated everywhere).
// CPU reference: src/render/drbokeh/bounds.rs `tile_bounds_cpu`.
//
// Bindings (set 0, std430):
//   0: rgba         readonly  vec4[layer_count * width * height]  premultiplied, layer-major
//   1: disparity    readonly  float[layer_count * width * height]
//   2: tile_bounds  writeonly vec2[layer_count * tiles_x * tiles_y] (support, gather) px
// Push constants: DrBokehPush (drbokeh.glsl); reads width, height, tiles_x, tiles_y, layer,
//   model, k_px, focus_disparity.
// Dispatch: (ceil(tiles_x * tiles_y / 256), 1, 1), once per layer.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 256, local_size_y = 1, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Rgba { vec4 rgba[]; };
layout(std430, set = 0, binding = 1) readonly buffer Disparity { float disparity[]; };
layout(std430, set = 0, binding = 2) writeonly buffer TileBounds { vec2 tile_bounds[]; };

float drbokeh_area_lut(int index) {
    return 1.0; // not used by this pass
}

float aperture_kernel_texel(int index) {
    return 0.0; // not used by this pass
}

void main() {
    int tiles = pc.tiles_x * pc.tiles_y;
    int t = int(gl_GlobalInvocationID.x);
    if (t >= tiles) {
        return;
    }
    int tx = t % pc.tiles_x;
    int ty = t / pc.tiles_x;
    int base = pc.layer * pc.width * pc.height;
    float support = 0.0;
    float gather = 0.0;
    for (int py = ty * DRBOKEH_TILE; py < min((ty + 1) * DRBOKEH_TILE, pc.height); ++py) {
        for (int px = tx * DRBOKEH_TILE; px < min((tx + 1) * DRBOKEH_TILE, pc.width); ++px) {
            int i = base + py * pc.width + px;
            float r = abs(pc.k_px * (disparity[i] - pc.focus_disparity));
            gather = max(gather, r + 0.5);
            if (rgba[i].w > 0.0) {
                support = max(support, drbokeh_support_for(r));
            }
        }
    }
    tile_bounds[pc.layer * tiles + t] = vec2(support, gather);
}
