// Body of the Dr.Bokeh layer pass (pass 2b of 3), compiled twice: glsl/drbokeh_layer_disk.comp
// defines DRBOKEH_LAYER_DISK (default model, disk aperture, the fast path) and
// glsl/drbokeh_layer.comp does not (every model and aperture). Two pipelines rather than a
// runtime branch so that neither carries the other's code: lavapipe runs branches under lane
// masks. Bindings, push constants and dispatch: see glsl/drbokeh_layer.comp.
#ifndef LENSBLUR_DRBOKEH_LAYER_GLSL
#define LENSBLUR_DRBOKEH_LAYER_GLSL

#include "drbokeh.glsl"

// Pixels per invocation, horizontally adjacent (a divisor of the 16 px tile): each source
// load serves RUN centres. The host derives RUN from local_size_x (16 / local_size_x).
// Measured on lavapipe (1024^2 five-layer frame, layer pass): RUN 1 1.40 s, 2 0.94 s, 4 1.42 s,
// 8 2.64 s. More centres keep more sums live (spilled), fewer load each source more often; at
// 2, an 8-lane SIMD row of invocations also shares one image row, so row bounds are uniform.
const int RUN = 2;

// 16 / RUN x 16 invocations of RUN pixels each: one 16x16 tile (one search window) per group.
layout(local_size_x = 8, local_size_y = 16, local_size_z = 1) in;
#include "dispatch.glsl"

#include "drbokeh_inputs.glsl"
layout(std430, set = 0, binding = 2) readonly buffer TileWindow { int tile_window[]; };
layout(std430, set = 0, binding = 5) writeonly buffer LayerCw { vec4 layer_cw[]; };
layout(std430, set = 0, binding = 6) writeonly buffer LayerVis { float layer_vis[]; };
// source_pa = P / A (vec4), source_sa = (s, alpha): texel buffers too.
layout(set = 0, binding = 7) uniform samplerBuffer source_pa;
layout(set = 0, binding = 8) uniform samplerBuffer source_sa;
layout(std430, set = 0, binding = 9) readonly buffer TileRadii { vec2 tile_radii[]; };
layout(set = 0, binding = 10) uniform samplerBuffer block_prefix;
layout(set = 0, binding = 11) uniform samplerBuffer block_suffix;
layout(set = 0, binding = 12) uniform samplerBuffer block_alpha;

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
    float s = texelFetch(source_sa, index).x;
    float alpha = texelFetch(source_sa, index).y;
    float r = abs(s);
    return Centre(s, r + 0.5, alpha * (1.0 - smoothstep(0.5, 1.5, r)), vec4(0.0), 0.0, 0.0);
}

// One tap of the disk path: source (pa = P / A, sa = (s, alpha)) at Euclidean gauge g;
// `inside` = the offset lies in the centre's window disk (taps outside add exact zeros).
// `occlusion` is a constant at each call: the occlusion-free loop does not evaluate it.
void disk_tap(inout Centre c, vec4 pa, vec2 sa, float g, bool inside, bool is_self, bool occlusion) {
    float s = smoothstep(0.0, 1.0, abs(sa.x) + 0.5 - g);
    if (occlusion && c.occluder > 0.0 && !is_self) {
        s *= 1.0 - c.occluder * (1.0 - smoothstep(-0.5, 0.0, sa.x - c.s));
    }
    float d = smoothstep(0.0, 1.0, c.support - g);
    s = inside ? s : 0.0;
    d = inside ? d : 0.0;
    c.cw += pa * s;
    c.vis_sum += sa.y * d;
    c.vis_weight += d;
}

// Largest |ox| with ox^2 + oy^2 < outer^2 within the window row: taps at gauge >= outer add exact
// zeros (both smoothsteps' arguments are <= 0 there: `outer` bounds every support, with a
// margin far above the f32 rounding of the gauges), so rows stop before them. The window
// `h` is an integer and rounds the reach up; for a layer of constant blur this drops the
// outer half pixel of the rim, up to a third of the rim taps.
int outer_half_width(float outer, int h, int oy) {
    if (outer >= float(h + 1)) {
        return row_half_width(h, oy);
    }
    // Inside the window's disk (outer < h + 1): the window row needs no test of its own.
    float room = outer * outer - float(oy * oy);
    return room <= 0.0 ? -1 : int(sqrt(room));
}

// An m in [-1, half_width] with t - g(m, oy) >= 1, g computed exactly as the gauges of
// gather_disk_run: every column |o| <= m of the row is then interior (g grows with |o|). The
// largest such m or one less: the estimate is off by a rounding at most, and only a too large
// one is settled with the exact test (a column short costs one full tap, and m stays a
// function of t and oy alone, so of global positions).
int interior_half_width(float t, float oy2, int half_width) {
    float room = max((t - 1.0) * (t - 1.0) - oy2, 0.0);
    int m = int(min(sqrt(room), float(half_width)));
    while (m >= 0 && t - sqrt(float(m * m) + oy2) < 1.0) {
        m -= 1;
    }
    return m;
}

// Full disk taps of columns [from, to] (offsets from x0) of one window row for all RUN
// centres, in x order: centre k's gauge is the one centre k - 1 had a column earlier.
void full_taps(inout Centre c[RUN], int row, int from, int to, int half_width, int oy, bool occlusion) {
    float oy2 = float(oy * oy);
    float g[RUN]; // g[k] = gauge of the current column from centre k
    for (int k = 1; k < RUN; ++k) {
        g[k] = sqrt(float((from - k) * (from - k)) + oy2);
    }
    for (int ox = from; ox <= to; ++ox) {
        vec4 pa = texelFetch(source_pa, row + ox);
        vec2 sa = texelFetch(source_sa, row + ox).xy;
        g[0] = sqrt(float(ox * ox) + oy2);
        for (int k = 0; k < RUN; ++k) {
            int o = ox - k;
            disk_tap(c[k], pa, sa, g[k], o >= -half_width && o <= half_width, o == 0 && oy == 0, occlusion);
        }
        for (int k = RUN - 1; k > 0; --k) {
            g[k] = g[k - 1];
        }
    }
}

// Sum of (P / A, alpha) over global columns [a, b] of one read row (`base` + x = read index of
// global column x), from the global 16-px blocks of drbokeh_layer_blocks.comp: within one
// block the columns left to right; else the suffix of a's block from a, the totals of the
// whole blocks between (left to right), then the prefix of b's block up to b. Which values
// enter depends on a and b only, and each is a function of global positions: the same bits
// for every read rect. Only block parts inside [a, b] (so inside the read rect) are read.
void span_sum(int base, int a, int b, out vec4 pa, out float alpha) {
    int block_a = a / DRBOKEH_TILE;
    int block_b = b / DRBOKEH_TILE;
    if (block_a == block_b) {
        if (a == block_a * DRBOKEH_TILE) {
            // The block's prefix is this very left-to-right sum.
            pa = texelFetch(block_prefix, base + b);
            alpha = texelFetch(block_alpha, base + b).x;
            return;
        }
        pa = vec4(0.0);
        alpha = 0.0;
        for (int x = a; x <= b; ++x) {
            pa += texelFetch(source_pa, base + x);
            alpha += texelFetch(source_sa, base + x).y;
        }
        return;
    }
    pa = texelFetch(block_suffix, base + a);
    alpha = texelFetch(block_alpha, base + a).y;
    for (int block = block_a + 1; block < block_b; ++block) {
        int first = base + block * DRBOKEH_TILE;
        pa += texelFetch(block_suffix, first);
        alpha += texelFetch(block_alpha, first).y;
    }
    pa += texelFetch(block_prefix, base + b);
    alpha += texelFetch(block_alpha, base + b).x;
}

// Default model, disk aperture: the terms of drbokeh_lens / drbokeh_scatter / drbokeh_occlusion
// with K = 1 and a Euclidean gauge, for RUN horizontally adjacent centres x0 + (k, 0) (same
// 16x16 tile, same window): each source is loaded once for all of them, and centre k's gauge
// is the one centre k - 1 had a column earlier. Each centre still sums its own taps in the
// first kernel's order.
//
// Interior: `t` <= every centre's support and <= fl(m + 1/2) for a lower bound m of |s| over
// the window's sources with alpha > 0 (tile_radii.x). Where t - g >= 1 both smoothsteps are
// exactly 1 (their argument is >= t - g by monotonic rounding), and sources with alpha <= 0
// have P / A = 0 exactly, so without occlusion a tap adds exactly (P / A, alpha, 1): the
// middle columns of each row, interior for all RUN centres, add one span sum (span_sum) and
// their count without any gauge. Another order than the full taps' (f32 rounding apart),
// but the span is a function of global positions, so still the same bits for every tiling.
void gather_disk_run(ivec2 x0, int h, float t, float outer, inout Centre c[RUN], bool occlusion) {
    int oy0 = max(-h, -x0.y);
    int oy1 = min(h, pc.height - 1 - x0.y);
    for (int oy = oy0; oy <= oy1; ++oy) {
        int half_width = outer_half_width(outer, h, oy);
        // Offsets from x0: centre k's row is [k - hw, k + hw], clipped to the image.
        int ox0 = max(-half_width, -x0.x);
        int ox1 = min(half_width + RUN - 1, pc.width - 1 - x0.x);
        int row = drbokeh_read_index(pc.layer, ivec2(x0.x, x0.y + oy));
        float oy2 = float(oy * oy);
        // Middle columns [mid0, mid1]: |ox - k| <= interior half-width for every centre k.
        int mid0 = ox1 + 1;
        int mid1 = ox1;
        if (!occlusion) {
            int interior = interior_half_width(t, oy2, half_width);
            int a = max(ox0, RUN - 1 - interior);
            int b = min(ox1, interior);
            if (a <= b) {
                mid0 = a;
                mid1 = b;
            }
        }
        full_taps(c, row, ox0, mid0 - 1, half_width, oy, occlusion);
        if (mid0 <= mid1) {
            vec4 pa;
            float alpha;
            span_sum(row - x0.x, x0.x + mid0, x0.x + mid1, pa, alpha);
            float count = float(mid1 - mid0 + 1);
            for (int k = 0; k < RUN; ++k) {
                c[k].cw += pa;
                c[k].vis_sum += alpha;
                c[k].vis_weight += count;
            }
        }
        full_taps(c, row, mid1 + 1, ox1, half_width, oy, occlusion);
    }
}

float visibility(float vis_sum, float vis_weight) {
    return vis_weight > 0.0 ? vis_sum / vis_weight : 0.0;
}

// Any model and aperture: the first kernel's per-tap terms over the clipped window disk.
void gather_general(ivec2 x, int h, out vec4 cw, out float vis) {
    int ix = drbokeh_read_index(pc.layer, x);
    float rel_x = texelFetch(disparity, ix).x - pc.focus_disparity;
    float s_x = pc.k_px * rel_x;
    float r_x = abs(s_x);
    float alpha_x = texelFetch(rgba, ix).w;
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
            vec4 p = texelFetch(rgba, iy);
            float rel_y = texelFetch(disparity, iy).x - pc.focus_disparity;
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

// Each invocation writes RUN horizontally adjacent pixels x0 + (k, 0) of the core.
void main() {
    uvec3 id = spread_global_invocation_id();
    ivec2 local = ivec2(RUN * id.x, id.y);
    if (local.x >= pc.core.z || local.y >= pc.core.w) {
        return;
    }
    ivec2 x0 = pc.core.xy + local;
    // Centres past the core (only at the image's right edge) repeat the last one, unwritten.
    int last = min(RUN, pc.core.z - local.x) - 1;
    int tile = pc.layer * pc.tiles_x * pc.tiles_y + (x0.y / DRBOKEH_TILE) * pc.tiles_x + x0.x / DRBOKEH_TILE;
    int h = tile_window[tile];
    vec4 cw[RUN];
    float vis[RUN];
#ifdef DRBOKEH_LAYER_DISK
    {
        Centre c[RUN];
        bool occluding = false;
        vec2 radii = tile_radii[tile];
        float t = radii.x + 0.5;
        for (int k = 0; k < RUN; ++k) {
            c[k] = centre_at(drbokeh_read_index(pc.layer, x0 + ivec2(min(k, last), 0)));
            occluding = occluding || c[k].occluder > 0.0;
            t = min(t, c[k].support);
        }
        // A margin far above f32 rounding: the interior test stays sound however the compiler
        // orders the adds of the tap's smoothstep arguments.
        t -= t * (1.0 / 65536.0);
        // Branches are masks on lavapipe: only a lane group with an occluding centre pays for
        // the occlusion terms.
        if (occluding) {
            gather_disk_run(x0, h, t, radii.y, c, true);
        } else {
            gather_disk_run(x0, h, t, radii.y, c, false);
        }
        for (int k = 0; k < RUN; ++k) {
            cw[k] = c[k].cw;
            vis[k] = visibility(c[k].vis_sum, c[k].vis_weight);
        }
    }
#else
    for (int k = 0; k < RUN; ++k) {
        gather_general(x0 + ivec2(min(k, last), 0), h, cw[k], vis[k]);
    }
#endif
    for (int k = 0; k <= last; ++k) {
        int out_index = drbokeh_core_index(pc.layer, x0 + ivec2(k, 0));
        layer_cw[out_index] = cw[k];
        layer_vis[out_index] = vis[k];
    }
}

#endif
