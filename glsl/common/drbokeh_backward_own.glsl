// Body of the Dr.Bokeh backward pass 2 (per receiver), compiled five times:
// glsl/drbokeh_backward_own_disk.comp defines DRBOKEH_BACKWARD_DISK (default model, disk
// aperture, no kernel image: V's weights with K = 1 and the Euclidean gauge),
// glsl/drbokeh_backward_own_gauge.comp also DRBOKEH_BACKWARD_GAUGE (the same with a polygon or
// ellipse and its closed-form gauge, glsl/common/gauge.glsl), glsl/drbokeh_backward_own_ring.comp
// DRBOKEH_BACKWARD_RING with the disk's (the ring's weight and dK/dr in closed form),
// glsl/drbokeh_backward_own_kernel.comp DRBOKEH_BACKWARD_KERNEL with the disk's (a kernel
// image's bilinear weight and dK/dr per tap) and glsl/drbokeh_backward_own.comp none (every model and aperture). Separate pipelines rather than a runtime branch: lavapipe runs every branch under lane masks. Bindings, push constants
// and dispatch: see glsl/drbokeh_backward_own.comp.
#ifndef LENSBLUR_DRBOKEH_BACKWARD_OWN_GLSL
#define LENSBLUR_DRBOKEH_BACKWARD_OWN_GLSL

#include "drbokeh_grad.glsl"
#ifdef DRBOKEH_BACKWARD_SPANS
#include "spans.glsl"
#endif
#ifdef DRBOKEH_BACKWARD_GAUGE
#include "gauge.glsl"
#endif

layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;
#include "dispatch.glsl"

#include "drbokeh_inputs.glsl"
layout(std430, set = 0, binding = 2) readonly buffer TileWindow { int tile_window[]; };
// Pass 1's adjoints, read per tap too (texelFetch).
layout(set = 0, binding = 5) uniform samplerBuffer adj_cw;
layout(set = 0, binding = 6) uniform samplerBuffer adj_vis;
layout(std430, set = 0, binding = 7) writeonly buffer Own { vec4 own[]; };
layout(std430, set = 0, binding = 8) writeonly buffer Receiver { vec4 receiver[]; };
#ifdef DRBOKEH_BACKWARD_SPANS
// The forward's alpha block sums in this batch (glsl/drbokeh_layer_blocks.comp, every layer):
// V's interior rows are span sums (receiver_visibility_sums).
layout(set = 0, binding = 9) uniform samplerBuffer block_alpha;
#define DRBOKEH_ALPHA_AT(i) texelFetch(rgba, i).w
DRBOKEH_DEFINE_SPAN_SUM(float, span_sum_alpha, DRBOKEH_ALPHA_AT, DRBOKEH_BLOCK_SCALAR_PREFIX, DRBOKEH_BLOCK_SCALAR_SUFFIX)
#endif

// Pass 2's pair terms of receiver x over its window: every one is a multiple of the scatter
// S(r_y, g) and of O's partials (any leak only enters through dS/dr_y, which pass 4 owns), so
// taps outside the source's support add exact zeros and are skipped. Returns (alpha, s, rel).
vec3 receiver_pair_terms(ivec2 x, int h, DrBokehPx dst, vec4 adj) {
    vec3 d_own = vec3(0.0);
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
            int iy = drbokeh_read_index(pc.layer, ivec2(sx, sy));
            vec4 p = texelFetch(rgba, iy);
            DrBokehPx src = drbokeh_px(texelFetch(disparity, iy).x, p.w);
            if (p.w > 0.0 && float(ox * ox + oy * oy) < drbokeh_zero_beyond2(drbokeh_support_for(src.r))) {
                float a = dot(adj, p);
                DrBokehPairGrad pg = drbokeh_pair_grad(vec2(float(-ox), float(-oy)), src, dst, ox == 0 && oy == 0);
                d_own += a * vec3(pg.alpha_x, pg.s_x, pg.rel_x);
            }
        }
    }
    return d_own;
}

// V(x)'s sums over the window rows clipped to offsets below sqrt(limit2): sum D, sum alpha D,
// sum D', sum alpha D' (D' = dD/dr_x), or the compat box count in .x. Spans path: where
// `interior` - g >= 1 (interior <= the receiver's support r + 1/2, with a margin above f32
// rounding), D is exactly 1 and D' exactly 0 (no leak), so those columns of a row add (1, alpha,
// 0, 0) each: their count and one span sum of alpha. The rim's taps are evaluated one by one.
vec4 receiver_visibility_sums(ivec2 x, int h, DrBokehPx dst, float limit2, float interior) {
    int box_half = drbokeh_visibility_box_compat(dst.r);
    vec4 vis = vec4(0.0);
    for (int oy = -h; oy <= h; ++oy) {
        int sy = x.y + oy;
        if (sy < 0 || sy >= pc.height) {
            continue;
        }
        int half_width = drbokeh_clipped_half_width(h, oy, limit2);
        // Columns |ox| <= m are interior (none with m = -1).
        int m = -1;
#ifdef DRBOKEH_BACKWARD_SPANS
        if (interior > 0.0) {
            m = interior_half_width_disk(interior, float(oy * oy), half_width);
            int a = max(x.x - m, 0);
            int b = min(x.x + m, pc.width - 1);
            if (a <= b) {
                int base = drbokeh_read_index(pc.layer, ivec2(a, sy)) - a;
                vis += vec4(float(b - a + 1), span_sum_alpha(base, a, b), 0.0, 0.0);
            }
        }
#endif
        for (int ox = -half_width; ox <= half_width; ++ox) {
            if (m >= 0 && ox == -m) {
                ox = m; // past the interior columns, summed above
                continue;
            }
            int sx = x.x + ox;
            if (sx < 0 || sx >= pc.width) {
                continue;
            }
#ifdef DRBOKEH_BACKWARD_DISK
            // drbokeh_vis_weight with K = 1, dK/dr = 0 and the Euclidean gauge (the shape's,
            // mirrored for a receiver nearer than focus, on the gauge path).
#ifdef DRBOKEH_BACKWARD_GAUGE
            vec2 gauges = gauge_pair(vec2(float(-ox), float(-oy)));
            float g = dst.s > 0.0 ? gauges.y : gauges.x;
#else
            float g = length(vec2(float(-ox), float(-oy)));
#endif
            float alpha = texelFetch(rgba, drbokeh_read_index(pc.layer, ivec2(sx, sy))).w;
            float d = drbokeh_footprint(dst.r, g);
            float d_d = drbokeh_leaky(drbokeh_d_footprint(dst.r, g));
#ifdef DRBOKEH_BACKWARD_RING
            // drbokeh_vis_weight's S K and d(S K)/dr_x.
            vec2 ring = drbokeh_ring_weight_d(g, dst.r);
            d_d = d_d * ring.x + d * ring.y;
            d *= ring.x;
#elif defined(DRBOKEH_BACKWARD_KERNEL)
            // The same with the kernel image's K and dK/dr at x - y in the receiver's aperture
            // coordinates.
            vec2 kernel = drbokeh_kernel_weight_d(aperture_coords(vec2(float(-ox), float(-oy)), dst.rel), dst.r);
            d_d = d_d * kernel.x + d * kernel.y;
            d *= kernel.x;
#endif
            vis += vec4(d, alpha * d, d_d, alpha * d_d);
#else
            if (pc.model == DRBOKEH_MODEL_COMPAT) {
                if (abs(ox) <= box_half && abs(oy) <= box_half) {
                    vis.x += 1.0;
                }
            } else {
                float alpha = texelFetch(rgba, drbokeh_read_index(pc.layer, ivec2(sx, sy))).w;
                vec2 d = drbokeh_vis_weight(vec2(float(-ox), float(-oy)), dst);
                vis += vec4(d.x, alpha * d.x, d.y, alpha * d.y);
            }
#endif
        }
    }
    return vis;
}

void main() {
#ifdef DRBOKEH_BACKWARD_GAUGE
    gauge_setup(pc.aperture, gauge_constants(pc.aperture));
#endif
    ivec2 x = drbokeh_core_pixel(spread_global_invocation_id());
    if (x.x < 0) {
        return;
    }
    int ix = drbokeh_read_index(pc.layer, x);
    int h = tile_window[pc.layer * pc.tiles_x * pc.tiles_y + (x.y / DRBOKEH_TILE) * pc.tiles_x + x.x / DRBOKEH_TILE];
    DrBokehPx dst = drbokeh_px(texelFetch(disparity, ix).x, texelFetch(rgba, ix).w);
    bool compat = pc.model == DRBOKEH_MODEL_COMPAT;
    // Taps that add exact zeros are skipped, by loop bounds (the sums are the reference's in
    // its order, less zeros): the pair terms need a receiver that can occlude (default model:
    // in focus, else O = 1 and its partials are 0), so the others run that loop zero times.
    // Exact default model: D and dD/dr_x vanish beyond the receiver's own support, so V's sums
    // visit only that disk; a leak keeps dD/dr_x over the whole square window.
    int pair_half = compat || drbokeh_occludes(dst) ? h : -1;
    vec3 d_own = receiver_pair_terms(x, pair_half, dst, texelFetch(adj_cw, ix));
    float limit2 = !compat && pc.leaky_slope <= 0.0 ? drbokeh_zero_beyond2(drbokeh_footprint_support(dst.r)) : 1.0e30;
    float interior = 0.0;
#ifdef DRBOKEH_BACKWARD_SPANS
    if (pc.leaky_slope <= 0.0) {
        interior = drbokeh_interior_bound(drbokeh_footprint_support(dst.r));
    }
#endif
    vec4 vis = receiver_visibility_sums(x, h, dst, limit2, interior);
    float d_vis = texelFetch(adj_vis, ix).x;
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
    receiver[ix] = vec4(dst.rel, dst.alpha, vis_norm, float(h));
}

#endif
