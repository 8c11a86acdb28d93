// Dr.Bokeh backward pass 2 of 4 (per layer): each pixel x as a receiver, over its forward
// window (same loops as drbokeh_layer.comp): dL/dalpha_x and dL/ds_x, dL/drel_x through the
// occlusion O(y, x) and V_l(x), and dL/dV_l(x) / sum D (normalised adjoint of V for pass 4).
// CPU reference: src/render/drbokeh/backward_cpu.rs `own_pixel`.
//
// Bindings (set 0, std430), "read" = the uploaded rect pc.read (it holds the window of every
// receiver of the core pc.core: the same rects as the forward's):
//   0: rgba         readonly  vec4[layer_count * read pixels]
//   1: disparity    readonly  float[layer_count * read pixels]
//   2: tile_window  readonly  int[layer_count * tiles_x * tiles_y] whole image (forward pass 1)
//   3: area_lut     readonly  float[area_count]
//   4: kernel       readonly  float[max(1, kernel_size^2)]
//   5: adj_cw       readonly  vec4[layer_count * read pixels]  (backward pass 1, core entries)
//   6: adj_vis      readonly  float[layer_count * read pixels]
//   7: own          writeonly vec4[layer_count * read pixels]  (alpha, s, rel, V / sum D), core entries
// Push constants: DrBokehPush (leaky_slope included).
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once per layer, after pass 1.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh_grad.glsl"

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Rgba { vec4 rgba[]; };
layout(std430, set = 0, binding = 1) readonly buffer Disparity { float disparity[]; };
layout(std430, set = 0, binding = 2) readonly buffer TileWindow { int tile_window[]; };
layout(std430, set = 0, binding = 3) readonly buffer AreaLut { float area_lut[]; };
layout(std430, set = 0, binding = 4) readonly buffer Kernel { float kernel_weights[]; };
layout(std430, set = 0, binding = 5) readonly buffer AdjCw { vec4 adj_cw[]; };
layout(std430, set = 0, binding = 6) readonly buffer AdjVis { float adj_vis[]; };
layout(std430, set = 0, binding = 7) writeonly buffer Own { vec4 own[]; };

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
    int ix = drbokeh_read_index(pc.layer, x);
    int h = tile_window[pc.layer * pc.tiles_x * pc.tiles_y + (x.y / DRBOKEH_TILE) * pc.tiles_x + x.x / DRBOKEH_TILE];
    DrBokehPx dst = drbokeh_px(disparity[ix], rgba[ix].w);
    vec4 adj = adj_cw[ix];
    int box_half = drbokeh_visibility_box_compat(dst.r);
    bool compat = pc.model == DRBOKEH_MODEL_COMPAT;

    // Taps that add exact zeros are skipped (the sums are the reference's in its order, less
    // zeros): the pair terms here are all multiples of the scatter S(r_y, g) and of O's
    // partials, so they need a receiver that can occlude (default model: in focus) and a tap
    // inside the source's support (any leak only enters through dS/dr_y). Exact default model:
    // D and dD/dr_x vanish beyond the receiver's own support, so an out-of-focus receiver visits
    // only that disk; a leak keeps dD/dr_x over the whole square window.
    bool occluding = compat || drbokeh_occludes(dst);
    float limit2 = 1.0e30;
    if (!occluding && pc.leaky_slope <= 0.0) {
        limit2 = drbokeh_zero_beyond2(drbokeh_support(dst.r));
    }
    vec3 d_own = vec3(0.0); // alpha, s, rel
    vec4 vis = vec4(0.0);   // sum D, sum alpha D, sum D', sum alpha D' (compat: box count)
    for (int oy = -h; oy <= h; ++oy) {
        int sy = x.y + oy;
        if (sy < 0 || sy >= pc.height) {
            continue;
        }
        int half_width = drbokeh_clipped_half_width(h, oy, limit2);
        for (int ox = -half_width; ox <= half_width; ++ox) {
            int sx = x.x + ox;
            if (sx < 0 || sx >= pc.width) {
                continue;
            }
            int iy = drbokeh_read_index(pc.layer, ivec2(sx, sy));
            vec4 p = rgba[iy];
            vec2 offset = vec2(float(-ox), float(-oy));
            if (occluding && p.w > 0.0) {
                DrBokehPx src = drbokeh_px(disparity[iy], p.w);
                if (float(ox * ox + oy * oy) < drbokeh_zero_beyond2(drbokeh_support_for(src.r))) {
                    float a = dot(adj, p);
                    DrBokehPairGrad pg = drbokeh_pair_grad(offset, src, dst, ox == 0 && oy == 0);
                    d_own += a * vec3(pg.alpha_x, pg.s_x, pg.rel_x);
                }
            }
            if (compat) {
                if (abs(ox) <= box_half && abs(oy) <= box_half) {
                    vis.x += 1.0;
                }
            } else {
                vec2 d = drbokeh_vis_weight(offset, dst);
                vis += vec4(d.x, p.w * d.x, d.y, p.w * d.y);
            }
        }
    }
    float d_vis = adj_vis[ix];
    float vis_norm = 0.0;
    if (vis.x > 0.0) {
        if (!compat) {
            // V = sum alpha D / sum D: dV/dr_x = (sum alpha D' sum D - sum alpha D sum D') / (sum D)^2.
            float d_v_dr = (vis.w * vis.x - vis.y * vis.z) / (vis.x * vis.x);
            d_own.y += d_vis * d_v_dr * drbokeh_sign(dst.s);
        }
        vis_norm = d_vis / vis.x;
    }
    own[ix] = vec4(d_own, vis_norm);
}
