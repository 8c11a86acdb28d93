// Body of the Dr.Bokeh backward pass 4 (per source), compiled five times:
// glsl/drbokeh_backward_source_disk.comp defines DRBOKEH_BACKWARD_DISK (default model, disk
// aperture, no kernel image: K = 1 and one Euclidean gauge per tap),
// glsl/drbokeh_backward_source_gauge.comp also DRBOKEH_BACKWARD_GAUGE (the same with a polygon
// or ellipse: K = 1, the shape's closed-form gauge, glsl/common/gauge.glsl, one per
// orientation), glsl/drbokeh_backward_source_ring.comp DRBOKEH_BACKWARD_RING with the disk's
// (the ring: its weight K(g, r) and dK/dr in closed form, drbokeh_ring_weight_d),
// glsl/drbokeh_backward_source_kernel.comp DRBOKEH_BACKWARD_KERNEL with the disk's (a kernel
// image: its bilinear weight and dK/dr per tap, drbokeh_kernel_weight_d), and
// glsl/drbokeh_backward_source.comp none (every model and aperture).
// Separate pipelines rather than a runtime branch: lavapipe runs every branch under lane masks, so a tap pays for all
// the code in the loop body, taken or not. Bindings, push constants and dispatch: see
// glsl/drbokeh_backward_source.comp.
#ifndef LENSBLUR_DRBOKEH_BACKWARD_SOURCE_GLSL
#define LENSBLUR_DRBOKEH_BACKWARD_SOURCE_GLSL

#include "drbokeh_grad.glsl"
#ifdef DRBOKEH_BACKWARD_GAUGE
#include "gauge.glsl"
#endif
#ifdef DRBOKEH_BACKWARD_SPANS
#ifdef DRBOKEH_BACKWARD_GAUGE
#error "interior spans skip receiver columns; the gauge path shifts its gauges column by column"
#endif
#include "spans.glsl"
#endif


#ifdef DRBOKEH_BACKWARD_DISK
// Sources per invocation, horizontally adjacent (a divisor of the 16 px tile, so they share
// the tile's reach): each receiver load serves RUN sources. The host derives RUN from
// local_size_x (16 / local_size_x).
const int RUN = 2;
layout(local_size_x = 8, local_size_y = 16, local_size_z = 1) in;
#else
layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;
#endif
#include "dispatch.glsl"

#include "drbokeh_inputs.glsl"
// Pass 2's receiver terms and pass 1's adjoints, read per tap too (texelFetch).
layout(set = 0, binding = 2) uniform samplerBuffer receiver;
layout(set = 0, binding = 5) uniform samplerBuffer adj_cw;
layout(set = 0, binding = 6) uniform samplerBuffer own;
layout(std430, set = 0, binding = 7) writeonly buffer GradRgba { vec4 grad_rgba[]; };
layout(std430, set = 0, binding = 8) writeonly buffer GradDisparity { float grad_disparity[]; };
layout(std430, set = 0, binding = 9) writeonly buffer KPartial { float k_partial[]; };
layout(std430, set = 0, binding = 10) readonly buffer TileReach { int tile_reach[]; };
#ifdef DRBOKEH_BACKWARD_SPANS
layout(set = 0, binding = 11) uniform samplerBuffer block_prefix;
layout(set = 0, binding = 12) uniform samplerBuffer block_suffix;
layout(set = 0, binding = 13) uniform samplerBuffer block_alpha;
layout(std430, set = 0, binding = 14) readonly buffer ReceiverRadius { float receiver_radius[]; };
#define DRBOKEH_ADJ_AT(i) texelFetch(adj_cw, i)
#define DRBOKEH_SHARE_AT(i) texelFetch(receiver, i).z
DRBOKEH_DEFINE_SPAN_SUM(vec4, span_sum_adjoint, DRBOKEH_ADJ_AT, DRBOKEH_BLOCK_PREFIX, DRBOKEH_BLOCK_SUFFIX)
DRBOKEH_DEFINE_SPAN_SUM(float, span_sum_share, DRBOKEH_SHARE_AT, DRBOKEH_BLOCK_SCALAR_PREFIX, DRBOKEH_BLOCK_SCALAR_SUFFIX)
#endif

// dV(x)/dalpha_y times sum D (own.w holds dL/dV / sum D).
float vis_share(vec2 offset, DrBokehPx dst) {
    if (pc.model == DRBOKEH_MODEL_COMPAT) {
        float half_width = float(drbokeh_visibility_box_compat(dst.r));
        return abs(offset.x) <= half_width && abs(offset.y) <= half_width ? 1.0 : 0.0;
    }
    return drbokeh_vis_weight(offset, dst).x;
}

#ifndef DRBOKEH_BACKWARD_DISK
void main() {
    ivec2 y = drbokeh_core_pixel(spread_global_invocation_id());
    if (y.x < 0) {
        return;
    }
    int tile_base = pc.layer * pc.tiles_x * pc.tiles_y;
    int iy = drbokeh_read_index(pc.layer, y);
    vec4 p = texelFetch(rgba, iy);
    DrBokehPx src = drbokeh_px(texelFetch(disparity, iy).x, p.w);
    vec4 own_y = texelFetch(own, iy);
    vec4 d_p = vec4(0.0, 0.0, 0.0, own_y.x);
    float d_s = own_y.y;
    float d_rel = own_y.z;
    int reach = tile_reach[tile_base + (y.y / DRBOKEH_TILE) * pc.tiles_x + y.x / DRBOKEH_TILE];
    bool compat = pc.model == DRBOKEH_MODEL_COMPAT;
    // Taps that add exact zeros are skipped (the sums are the reference's in its order, less
    // zeros). Exact gradient: the pair terms vanish beyond the source's support (S and dS/dr_y
    // are 0 there), and V(x)'s share beyond x's own support r_x + 1/2 <= h_x + 1 <= reach + 1
    // (the compat box lies inside it too), so only the disk of radius reach + 1 is visited. A
    // leak keeps dS/dr_y on every receiver whose square window holds y.
    bool exact = pc.leaky_slope <= 0.0;
    float loop_limit2 = exact ? float((reach + 1) * (reach + 1)) : 1.0e30;
    float pair_limit2 = exact ? drbokeh_zero_beyond2(drbokeh_support_for(src.r)) : 1.0e30;
    for (int oy = -reach; oy <= reach; ++oy) {
        int ry = y.y + oy;
        if (ry < 0 || ry >= pc.height) {
            continue;
        }
        int half_width = drbokeh_clipped_half_width(reach, oy, loop_limit2);
        for (int ox = -half_width; ox <= half_width; ++ox) {
            int rx = y.x + ox;
            if (rx < 0 || rx >= pc.width) {
                continue;
            }
            // One load per receiver: its window, inputs and V adjoint (pass 2's `receiver`).
            int ix = drbokeh_read_index(pc.layer, ivec2(rx, ry));
            vec4 rcv = texelFetch(receiver, ix);
            int h = int(rcv.w);
            if (abs(ox) > h || abs(oy) > h) {
                continue; // the receiver's window does not hold this source
            }
            float s_x = pc.k_px * rcv.x; // as drbokeh_px
            DrBokehPx dst = DrBokehPx(rcv.x, s_x, abs(s_x), rcv.y);
            vec2 offset = vec2(float(ox), float(oy));
            float o2 = float(ox * ox + oy * oy);
            bool pair = p.w > 0.0 && o2 < pair_limit2;
            vec4 adj = texelFetch(adj_cw, ix);
            float a = dot(adj, p);
            float own_share = rcv.z;
            if (pair) {
                DrBokehPairGrad pg = drbokeh_pair_grad(offset, src, dst, ox == 0 && oy == 0);
                d_p += adj * pg.w;
                d_s += a * pg.s_y;
                d_rel += a * pg.rel_y;
            }
            // V(x)'s share is 0 beyond x's own support r_x + 1/2.
            if (own_share != 0.0 && (compat || o2 < drbokeh_zero_beyond2(drbokeh_footprint_support(dst.r)))) {
                d_p.w += own_share * vis_share(offset, dst);
            }
        }
    }
    int out_index = drbokeh_core_index(pc.layer, y);
    grad_rgba[out_index] = d_p;
    grad_disparity[out_index] = pc.k_px * d_s + d_rel;
    k_partial[out_index] = src.rel * d_s;
}

#else
// Disk path: drbokeh_pair_grad and drbokeh_vis_weight with K = 1, dK/dr = 0 and the one
// Euclidean gauge |x - y| (the mirror of aperture_coords keeps the length), for RUN
// horizontally adjacent sources y0 + (k, 0): each receiver is loaded once for all of them, and
// each source still sums its receivers in the order of one source per invocation. Gauge path:
// the same with the shape's gauge of x - y, mirrored for the source's or receiver's side of
// focus; source k's gauges at receiver column o are those source k - 1 had a column earlier.
void main() {
#ifdef DRBOKEH_BACKWARD_GAUGE
    gauge_setup(pc.aperture, gauge_constants(pc.aperture));
#endif
    uvec3 id = spread_global_invocation_id();
    ivec2 local = ivec2(RUN * id.x, id.y);
    if (local.x >= pc.core.z || local.y >= pc.core.w) {
        return;
    }
    ivec2 y0 = pc.core.xy + local;
    // Sources past the core (only at the image's right edge) repeat the last one, unwritten.
    int last = min(RUN, pc.core.z - local.x) - 1;
    int tile_base = pc.layer * pc.tiles_x * pc.tiles_y;
    int reach = tile_reach[tile_base + (y0.y / DRBOKEH_TILE) * pc.tiles_x + y0.x / DRBOKEH_TILE];
    // Loop bounds and skipped zeros as in the general main above.
    bool exact = pc.leaky_slope <= 0.0;
    float loop_limit2 = exact ? float((reach + 1) * (reach + 1)) : 1.0e30;
    vec4 p[RUN];
    DrBokehPx src[RUN];
    float pair_limit2[RUN];
    float area[RUN];
    float d_area[RUN];
    float sign_y[RUN];
    vec4 d_p[RUN];
    float d_s[RUN];
    for (int k = 0; k < RUN; ++k) {
        int iy = drbokeh_read_index(pc.layer, y0 + ivec2(min(k, last), 0));
        p[k] = texelFetch(rgba, iy);
        src[k] = drbokeh_px(texelFetch(disparity, iy).x, p[k].w);
        pair_limit2[k] = exact ? drbokeh_zero_beyond2(drbokeh_support(src[k].r)) : 1.0e30;
        area[k] = drbokeh_area(src[k].r);
        d_area[k] = drbokeh_d_area(src[k].r);
        sign_y[k] = drbokeh_sign(src[k].s);
        vec4 own_y = texelFetch(own, iy);
        d_p[k] = vec4(0.0, 0.0, 0.0, own_y.x);
        d_s[k] = own_y.y; // d_rel stays own_y.z: the default model has no rel_y term
    }
#ifdef DRBOKEH_BACKWARD_SPANS
    // Interior: receivers at gauge g with t[k] - g >= 1, where t[k] is below both source k's
    // support (its coverage radius + 1/2) and every receiver's own (its radius + 1/2, from
    // the tile's smallest receiver radius), with margins above f32 rounding. There S = 1,
    // dS/dr = 0 (no leak) and D = 1; and as every receiver's radius is >= 3/2 there, none is
    // in focus, so O = 1 and dO = 0: each adds its adjoints alone, d_p += adj / A,
    // d_s += dot(adj, P) (-A' / A^2) sign, d_p.w += dL/dV / sum D. A row's interior is one span
    // sum of each (pass 3' block sums) instead of a tap per receiver.
    float t[RUN];
    {
        float smallest = receiver_radius[tile_base + (y0.y / DRBOKEH_TILE) * pc.tiles_x + y0.x / DRBOKEH_TILE];
        float t_receiver = drbokeh_interior_bound(smallest + 0.5);
        for (int k = 0; k < RUN; ++k) {
            float t_source = drbokeh_interior_bound(drbokeh_coverage_radius(src[k].r) + 0.5);
            t[k] = exact && smallest >= 1.5 ? min(t_source, t_receiver) : 0.0;
        }
    }
#endif
    for (int oy = -reach; oy <= reach; ++oy) {
        int ry = y0.y + oy;
        if (ry < 0 || ry >= pc.height) {
            continue;
        }
        int half_width = drbokeh_clipped_half_width(reach, oy, loop_limit2);
        // Receivers y0 + (o, oy), o in [-half_width, half_width + RUN - 1] clipped to the
        // image: source k sees the offset (o - k, oy).
        int o0 = max(-half_width, -y0.x);
        int o1 = min(half_width + RUN - 1, pc.width - 1 - y0.x);
        // Receivers [skip0, skip1] lie in the interior of every source of the run: each adds
        // its adjoints alone to each source, as one span sum, and the taps below skip them
        // (none with skip0 = o1 + 1). One range for the run, not one per source: a bound per
        // source read at every tap made the pass twice as slow on lavapipe, whose tap loop
        // holds each live value in a 256-bit register per 8 lanes.
        int skip0 = o1 + 1;
        int skip1 = o1;
#ifdef DRBOKEH_BACKWARD_SPANS
        skip0 = o0;
        for (int k = 0; k < RUN; ++k) {
            int m = t[k] > 1.0 ? interior_half_width_disk(t[k], float(oy * oy), half_width) : -1;
            skip0 = max(skip0, k - m);
            skip1 = min(skip1, k + m);
        }
        if (skip0 <= skip1) {
            int a = y0.x + skip0;
            int b = y0.x + skip1;
            int base = drbokeh_read_index(pc.layer, ivec2(a, ry)) - a;
            vec4 adj = span_sum_adjoint(base, a, b);
            float share = span_sum_share(base, a, b);
            for (int k = 0; k < RUN; ++k) {
                if (p[k].w > 0.0) {
                    d_p[k] += adj * (1.0 / area[k]);
                    d_s[k] += dot(adj, p[k]) * (-d_area[k] / area[k] / area[k] * sign_y[k]);
                }
                d_p[k].w += share;
            }
        } else {
            skip0 = o1 + 1;
        }
#endif
#ifdef DRBOKEH_BACKWARD_GAUGE
        // gauges[k] = gauge_pair of x - y for source k at the current column: (G, mirrored G).
        vec2 gauges[RUN];
        for (int k = 1; k < RUN; ++k) {
            gauges[k] = gauge_pair(vec2(float(o0 - k), float(oy)));
        }
#endif
        for (int o = o0; o <= o1; ++o) {
            if (o == skip0) {
                o = skip1; // past the receivers summed above
                continue;
            }
#ifdef DRBOKEH_BACKWARD_GAUGE
            if (o > o0) {
                for (int k = RUN - 1; k > 0; --k) {
                    gauges[k] = gauges[k - 1];
                }
            }
            gauges[0] = gauge_pair(vec2(float(o), float(oy)));
#endif
            int ix = drbokeh_read_index(pc.layer, ivec2(y0.x + o, ry));
            vec4 rcv = texelFetch(receiver, ix);
            int h = int(rcv.w);
            if (abs(oy) > h) {
                continue; // the receiver's window holds no source of this row
            }
            float s_x = pc.k_px * rcv.x; // as drbokeh_px
            DrBokehPx dst = DrBokehPx(rcv.x, s_x, abs(s_x), rcv.y);
            vec4 adj = texelFetch(adj_cw, ix);
            float own_share = rcv.z;
            float vis_limit2 = drbokeh_zero_beyond2(drbokeh_footprint_support(dst.r));
            // A receiver out of focus or transparent cannot occlude: O = 1 and dO/ds_y = 0
            // exactly, so only lane groups with an occluding receiver evaluate them.
            bool occluding = drbokeh_occludes(dst) && dst.alpha != 0.0;
            for (int k = 0; k < RUN; ++k) {
                int ox = o - k;
                if (ox < -half_width || ox > half_width || abs(ox) > h) {
                    continue; // outside source k's row or the receiver's window
                }
                vec2 offset = vec2(float(ox), float(oy));
                float o2 = float(ox * ox + oy * oy);
#ifdef DRBOKEH_BACKWARD_GAUGE
                // aperture_coords: a side nearer than focus sees x - y mirrored.
                float g = src[k].s > 0.0 ? gauges[k].y : gauges[k].x;
                float g_receiver = dst.s > 0.0 ? gauges[k].y : gauges[k].x;
#else
                float g = length(offset);
                float g_receiver = g;
#endif
                float s = drbokeh_scatter(src[k].r, g);
                float ds = drbokeh_leaky(drbokeh_d_scatter(src[k].r, g));
#ifdef DRBOKEH_BACKWARD_RING
                // drbokeh_pair_grad's S K and d(S K)/dr_y.
                vec2 ring = drbokeh_ring_weight_d(g, src[k].r);
                ds = ds * ring.x + s * ring.y;
                s *= ring.x;
#elif defined(DRBOKEH_BACKWARD_KERNEL)
                // The same with the kernel image's K and dK/dr at x - y in the source's
                // aperture coordinates; a tap outside the soft disk (S = 0, dS/dr = 0) needs none.
                if (s != 0.0 || ds != 0.0) {
                    vec2 kernel = drbokeh_kernel_weight_d(aperture_coords(offset, src[k].rel), src[k].r);
                    ds = ds * kernel.x + s * kernel.y;
                    s *= kernel.x;
                }
#endif
                bool is_self = ox == 0 && oy == 0;
                float occ = 1.0;
                float d_occ = 0.0;
                if (occluding) {
                    occ = drbokeh_occlusion(src[k].s, dst.s, dst.r, dst.alpha, is_self);
                    d_occ = drbokeh_d_occlusion(src[k].s, dst.s, dst.r, dst.alpha, is_self).x;
                }
                float base = s / area[k];
                float d_r_y = (ds - s * d_area[k] / area[k]) * occ / area[k];
                if (p[k].w > 0.0 && o2 < pair_limit2[k]) {
                    d_p[k] += adj * (base * occ);
                    d_s[k] += dot(adj, p[k]) * (d_r_y * sign_y[k] + base * d_occ);
                }
                if (own_share != 0.0 && o2 < vis_limit2) {
#ifdef DRBOKEH_BACKWARD_RING
                    d_p[k].w += own_share * (drbokeh_footprint(dst.r, g_receiver) * drbokeh_ring_weight_d(g_receiver, dst.r).x);
#elif defined(DRBOKEH_BACKWARD_KERNEL)
                    vec2 p_receiver = aperture_coords(offset, dst.rel);
                    d_p[k].w += own_share * (drbokeh_footprint(dst.r, g_receiver) * drbokeh_kernel_weight_d(p_receiver, dst.r).x);
#else
                    d_p[k].w += own_share * drbokeh_footprint(dst.r, g_receiver);
#endif
                }
            }
        }
    }
    for (int k = 0; k <= last; ++k) {
        int iy = drbokeh_read_index(pc.layer, y0 + ivec2(k, 0));
        int out_index = drbokeh_core_index(pc.layer, y0 + ivec2(k, 0));
        grad_rgba[out_index] = d_p[k];
        grad_disparity[out_index] = pc.k_px * d_s[k] + texelFetch(own, iy).z;
        k_partial[out_index] = src[k].rel * d_s[k];
    }
}
#endif

#endif
