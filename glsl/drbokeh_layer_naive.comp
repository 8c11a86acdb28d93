// BENCHMARK BASELINE: the first straightforward Dr.Bokeh layer kernel, kept unchanged so
// `lensblur bench perf` can measure the speed-up of glsl/drbokeh_layer.comp in the same run
// (`LayerKernel::Baseline`). Same bindings, push constants and results (within f32 rounding).
//
// Dr.Bokeh pass 2 of 3 (per layer): C_l, W_l and V_l of every pixel, gathered over its tile's
// window. C_l = sum_y P(y) S K O / A (P premultiplied RGB), W_l = sum_y a(y) S K O / A,
// V_l = soft-disk mean alpha over x's CoC (default) or the released square box (compat).
// CPU reference: src/render/drbokeh/cpu.rs `layer_pixel` (same loops, same order).
//
// Bindings (set 0, std430), "read" = the uploaded rect pc.read, "core" = the frame tile pc.core:
//   0: rgba         readonly  vec4[layer_count * read pixels]      premultiplied, layer-major
//   1: disparity    readonly  float[layer_count * read pixels]
//   2: tile_window  readonly  int[layer_count * tiles_x * tiles_y] whole image, bounds.rs
//   3: area_lut     readonly  float[area_count]                    Params::area_lut_f32
//   4: kernel       readonly  float[max(1, kernel_size^2)]         Params::kernel_f32
//   5: layer_cw     vec4[layer_count * core pixels]      (C_l.rgb, W_l); with pc.fold the
//                   running composite (premultiplied RGBA) of the layers so far, over the core
//   6: layer_vis    float[layer_count * core pixels]     V_l; with pc.fold the transmittance
// Push constants: DrBokehPush (all fields but max_support). The read rect holds every source
// within the window of every pixel of the core; borders are the image's, not the tile's.
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once per layer.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Rgba { vec4 rgba[]; };
layout(std430, set = 0, binding = 1) readonly buffer Disparity { float disparity[]; };
layout(std430, set = 0, binding = 2) readonly buffer TileWindow { int tile_window[]; };
layout(std430, set = 0, binding = 3) readonly buffer AreaLut { float area_lut[]; };
layout(std430, set = 0, binding = 4) readonly buffer Kernel { float kernel_weights[]; };
#include "drbokeh_layer_out.glsl"

float drbokeh_area_lut(int index) {
    return area_lut[index];
}

float aperture_kernel_texel(int index) {
    return kernel_weights[index];
}

void main() {
    ivec2 x = drbokeh_core_pixel(gl_GlobalInvocationID);
    if (x.x < 0) {
        return;
    }
    int ix = drbokeh_read_index(pc.slot, x);
    int h = tile_window[pc.layer * pc.tiles_x * pc.tiles_y + (x.y / DRBOKEH_TILE) * pc.tiles_x + x.x / DRBOKEH_TILE];
    float rel_x = disparity[ix] - pc.focus_disparity;
    float s_x = pc.k_px * rel_x;
    float r_x = abs(s_x);
    float alpha_x = rgba[ix].w;
    int box_half = drbokeh_visibility_box_compat(r_x);
    bool compat = pc.model == DRBOKEH_MODEL_COMPAT;

    vec4 cw = vec4(0.0);
    float vis_sum = 0.0;
    float vis_weight = 0.0;
    for (int oy = -h; oy <= h; ++oy) {
        int sy = x.y + oy;
        if (sy < 0 || sy >= pc.height) {
            continue;
        }
        for (int ox = -h; ox <= h; ++ox) {
            int sx = x.x + ox;
            if (sx < 0 || sx >= pc.width) {
                continue;
            }
            int iy = drbokeh_read_index(pc.slot, ivec2(sx, sy));
            vec4 p = rgba[iy];
            float rel_y = disparity[iy] - pc.focus_disparity;
            float s_y = pc.k_px * rel_y;
            float r_y = abs(s_y);
            // Offset x - y: the lens term is evaluated where the source lands.
            vec2 offset = vec2(float(-ox), float(-oy));
            bool is_self = ox == 0 && oy == 0;

            if (p.w > 0.0) {
                vec2 lens = drbokeh_lens(offset, r_y, rel_y);
                float s = compat ? drbokeh_scatter_compat(r_y, lens.x) : drbokeh_scatter(r_y, lens.x);
                float o = compat ? drbokeh_occlusion_compat(rel_y, rel_x, r_x, is_self)
                                 : drbokeh_occlusion(s_y, s_x, r_x, alpha_x, is_self);
                float weight = s * lens.y * o / drbokeh_area_for(r_y);
                cw.xyz += p.xyz * weight;
                cw.w += p.w * weight;
            }

            if (compat) {
                if (abs(ox) <= box_half && abs(oy) <= box_half) {
                    vis_sum += p.w;
                    vis_weight += 1.0;
                }
            } else {
                vec2 lens = drbokeh_lens(offset, r_x, rel_x);
                float d = drbokeh_footprint(r_x, lens.x) * lens.y;
                vis_sum += p.w * d;
                vis_weight += d;
            }
        }
    }
    drbokeh_layer_out(drbokeh_core_index(pc.slot, x), cw, vis_weight > 0.0 ? vis_sum / vis_weight : 0.0);
}
