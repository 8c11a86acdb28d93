// Dr.Bokeh pass 2b of 3 (per layer): C_l, W_l and V_l of every pixel, gathered over its tile's
// window. C_l = sum_y P(y) S K O / A (P premultiplied RGB), W_l = sum_y a(y) S K O / A,
// V_l = soft-disk mean alpha over x's CoC (default) or the released square box (compat).
// CPU reference: src/render/drbokeh/cpu.rs `layer_pixel` (same taps, same order).
//
// Why it is faster than the first kernel (kept as glsl/drbokeh_layer_naive.comp, the
// benchmark baseline):
// - Taps outside the Euclidean disk of radius h + 1 are skipped: h = ceil(reach) - 1 and every
//   gauge is at least the Euclidean length, so their S, K and V terms are exactly 0 (pi/4 of
//   the square). Rows and columns are clipped to the image instead of tested per tap.
// - Default model, disk aperture (the common case): P / A(r_y), s_y and alpha_y come from the
//   per-source prepass (drbokeh_layer_sources.comp), one gauge serves the scatter and the
//   visibility, the in-layer occlusion is evaluated only for centres that can occlude
//   (alpha_x * in_focus(r_x) > 0; elsewhere O = 1 exactly), and each invocation gathers two
//   adjacent pixels from one load per source (loads are per-lane gathers on lavapipe).
// - Every other model or aperture runs the first kernel's per-tap terms over the clipped disk.
//
// Bindings (set 0, std430), "read" = the uploaded rect pc.read, "core" = the frame tile pc.core:
//   0: rgba         readonly  vec4[layer_count * read pixels]      premultiplied, layer-major
//   1: disparity    readonly  float[layer_count * read pixels]
//   2: tile_window  readonly  int[layer_count * tiles_x * tiles_y] whole image, bounds.rs
//   3: area_lut     readonly  float[area_count]                    Params::area_lut_f32
//   4: kernel       readonly  float[max(1, kernel_size^2)]         Params::kernel_f32
//   5: layer_cw     writeonly vec4[layer_count * core pixels]      (C_l.rgb, W_l)
//   6: layer_vis    writeonly float[layer_count * core pixels]     V_l
//   7: source_pa    readonly  vec4[layer_count * read pixels]      P / A(r), prepass
//   8: source_sa    readonly  vec2[layer_count * read pixels]      (s, alpha), prepass
// Push constants: DrBokehPush (all fields but max_support). The read rect holds every source
// within the window of every pixel of the core; borders are the image's, not the tile's.
// Dispatch: (ceil(core width / 16), ceil(core height / 16), 1), once per layer (the host asks
// groups_for(ceil(core width / 2), core height): two pixels per invocation).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "drbokeh.glsl"

// 8 x 16 invocations of two pixels each: one 16x16 tile (one search window) per workgroup.
layout(local_size_x = 8, local_size_y = 16, local_size_z = 1) in;

layout(std430, set = 0, binding = 0) readonly buffer Rgba { vec4 rgba[]; };
layout(std430, set = 0, binding = 1) readonly buffer Disparity { float disparity[]; };
layout(std430, set = 0, binding = 2) readonly buffer TileWindow { int tile_window[]; };
layout(std430, set = 0, binding = 3) readonly buffer AreaLut { float area_lut[]; };
layout(std430, set = 0, binding = 4) readonly buffer Kernel { float kernel_weights[]; };
layout(std430, set = 0, binding = 5) writeonly buffer LayerCw { vec4 layer_cw[]; };
layout(std430, set = 0, binding = 6) writeonly buffer LayerVis { float layer_vis[]; };
layout(std430, set = 0, binding = 7) readonly buffer SourcePa { vec4 source_pa[]; };
layout(std430, set = 0, binding = 8) readonly buffer SourceSa { vec2 source_sa[]; };

float drbokeh_area_lut(int index) {
    return area_lut[index];
}

float aperture_kernel_texel(int index) {
    return kernel_weights[index];
}

// Largest |ox| with ox^2 + oy^2 < (h + 1)^2: the row of the window disk at height oy.
int row_half_width(int h, int oy) {
    int room = (h + 1) * (h + 1) - oy * oy;
    int half_width = int(sqrt(float(room)));
    // sqrt is correctly rounded and room < 2^24, so this corrects a perfect square only.
    if (half_width * half_width >= room) {
        half_width -= 1;
    }
    return half_width;
}

// One output pixel's centre terms and running sums on the disk path.
struct Centre {
    float s;        // signed CoC radius
    float support;  // r + 1/2: V gathers where the gauge is below it
    float occluder; // alpha * in_focus(r): O = 1 - occluder * behind; 0 (O = 1) at most centres
    vec4 cw;
    float vis_sum;
    float vis_weight;
};

Centre centre_at(int index) {
    float s = source_sa[index].x;
    float alpha = source_sa[index].y;
    float r = abs(s);
    return Centre(s, r + 0.5, alpha * (1.0 - smoothstep(0.5, 1.5, r)), vec4(0.0), 0.0, 0.0);
}

// One tap of the disk path: source (pa = P / A, sa = (s, alpha)) at Euclidean gauge g;
// `inside` = the offset lies in the centre's window disk (taps outside add exact zeros).
void disk_tap(inout Centre c, vec4 pa, vec2 sa, float g, bool inside, bool is_self) {
    float s = smoothstep(0.0, 1.0, abs(sa.x) + 0.5 - g);
    if (c.occluder > 0.0 && !is_self) {
        s *= 1.0 - c.occluder * (1.0 - smoothstep(-0.5, 0.0, sa.x - c.s));
    }
    float d = smoothstep(0.0, 1.0, c.support - g);
    s = inside ? s : 0.0;
    d = inside ? d : 0.0;
    c.cw += pa * s;
    c.vis_sum += sa.y * d;
    c.vis_weight += d;
}

// Default model, disk aperture: the terms of drbokeh_lens / drbokeh_scatter / drbokeh_occlusion
// with K = 1 and a Euclidean gauge, for two horizontally adjacent centres a and b = a + (1, 0)
// (same 16x16 tile, same window): each source is loaded once for both, and b's gauge is the
// one a had a column earlier. Each centre still sums its own taps in the first kernel's order.
void gather_disk_pair(ivec2 xa, int h, inout Centre a, inout Centre b) {
    int oy0 = max(-h, -xa.y);
    int oy1 = min(h, pc.height - 1 - xa.y);
    for (int oy = oy0; oy <= oy1; ++oy) {
        int half_width = row_half_width(h, oy);
        // Offsets from a: a's row is [-hw, hw], b's is [-hw + 1, hw + 1], both clipped.
        int ox0 = max(-half_width, -xa.x);
        int ox1 = min(half_width + 1, pc.width - 1 - xa.x);
        int row = drbokeh_read_index(pc.layer, ivec2(xa.x, xa.y + oy));
        float oy2 = float(oy * oy);
        float g_b = sqrt(float((ox0 - 1) * (ox0 - 1)) + oy2);
        for (int ox = ox0; ox <= ox1; ++ox) {
            vec4 pa = source_pa[row + ox];
            vec2 sa = source_sa[row + ox];
            float g_a = sqrt(float(ox * ox) + oy2);
            disk_tap(a, pa, sa, g_a, ox <= half_width, ox == 0 && oy == 0);
            disk_tap(b, pa, sa, g_b, ox > -half_width, ox == 1 && oy == 0);
            g_b = g_a;
        }
    }
}

float visibility(float vis_sum, float vis_weight) {
    return vis_weight > 0.0 ? vis_sum / vis_weight : 0.0;
}

// Any model and aperture: the first kernel's per-tap terms over the clipped window disk.
void gather_general(ivec2 x, int h, out vec4 cw, out float vis) {
    int ix = drbokeh_read_index(pc.layer, x);
    float rel_x = disparity[ix] - pc.focus_disparity;
    float s_x = pc.k_px * rel_x;
    float r_x = abs(s_x);
    float alpha_x = rgba[ix].w;
    int box_half = drbokeh_visibility_box_compat(r_x);
    bool compat = pc.model == DRBOKEH_MODEL_COMPAT;
    cw = vec4(0.0);
    float vis_sum = 0.0;
    float vis_weight = 0.0;
    int oy0 = max(-h, -x.y);
    int oy1 = min(h, pc.height - 1 - x.y);
    for (int oy = oy0; oy <= oy1; ++oy) {
        int half_width = row_half_width(h, oy);
        int ox0 = max(-half_width, -x.x);
        int ox1 = min(half_width, pc.width - 1 - x.x);
        int row = drbokeh_read_index(pc.layer, ivec2(x.x, x.y + oy));
        for (int ox = ox0; ox <= ox1; ++ox) {
            int iy = row + ox;
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
                float d = drbokeh_scatter(r_x, lens.x) * lens.y;
                vis_sum += p.w * d;
                vis_weight += d;
            }
        }
    }
    vis = visibility(vis_sum, vis_weight);
}

// Each invocation writes two horizontally adjacent pixels (a, b = a + (1, 0)) of the core.
void main() {
    ivec2 local = ivec2(2 * gl_GlobalInvocationID.x, gl_GlobalInvocationID.y);
    if (local.x >= pc.core.z || local.y >= pc.core.w) {
        return;
    }
    bool has_b = local.x + 1 < pc.core.z;
    ivec2 xa = pc.core.xy + local;
    ivec2 xb = xa + ivec2(has_b ? 1 : 0, 0);
    int h = tile_window[pc.layer * pc.tiles_x * pc.tiles_y + (xa.y / DRBOKEH_TILE) * pc.tiles_x + xa.x / DRBOKEH_TILE];
    bool disk = pc.model == DRBOKEH_MODEL_DRBOKEH && pc.aperture.x < 3.0 && (pc.aperture.w < 0.5 || pc.kernel_size == 0);
    vec4 cw_a;
    vec4 cw_b;
    float vis_a;
    float vis_b;
    if (disk) {
        Centre a = centre_at(drbokeh_read_index(pc.layer, xa));
        Centre b = centre_at(drbokeh_read_index(pc.layer, xb));
        gather_disk_pair(xa, h, a, b);
        cw_a = a.cw;
        cw_b = b.cw;
        vis_a = visibility(a.vis_sum, a.vis_weight);
        vis_b = visibility(b.vis_sum, b.vis_weight);
    } else {
        gather_general(xa, h, cw_a, vis_a);
        gather_general(xb, h, cw_b, vis_b);
    }
    layer_cw[drbokeh_core_index(pc.layer, xa)] = cw_a;
    layer_vis[drbokeh_core_index(pc.layer, xa)] = vis_a;
    if (has_b) {
        layer_cw[drbokeh_core_index(pc.layer, xb)] = cw_b;
        layer_vis[drbokeh_core_index(pc.layer, xb)] = vis_b;
    }
}
