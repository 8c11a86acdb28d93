// Body of the Dr.Bokeh layer pass (pass 2b of 3), compiled five times:
// glsl/drbokeh_layer_disk.comp defines DRBOKEH_LAYER_DISK (default model, disk aperture),
// glsl/drbokeh_layer_gauge.comp DRBOKEH_LAYER_GAUGE (default model, polygon or ellipse: the
// same span path with row bounds from the aperture's row table and the shape's gauge in the
// rim taps), glsl/drbokeh_layer_ring.comp DRBOKEH_LAYER_RING (default model, ring: the disk
// path's gather, then the obstruction's, subtracted), glsl/drbokeh_layer_kernel.comp
// DRBOKEH_LAYER_KERNEL (default model, kernel image: the disk path's rows split into the
// kernel's runs of full-weight cells, summed, and of zero-weight cells, skipped, with the kernel
// sampled only at the taps between; src/camera/kernel_runs.rs) and glsl/drbokeh_layer.comp
// none of them (every model and aperture, per tap).
// Separate pipelines rather than a runtime branch so that none carries another's code: lavapipe
// runs branches under lane masks. Bindings, push constants and dispatch: see
// glsl/drbokeh_layer.comp.
#ifndef LENSBLUR_DRBOKEH_LAYER_GLSL
#define LENSBLUR_DRBOKEH_LAYER_GLSL

#if defined(DRBOKEH_LAYER_DISK) || defined(DRBOKEH_LAYER_RING) || defined(DRBOKEH_LAYER_KERNEL)
// The disk's row bounds: the ring's rim is the disk's, a kernel image lies in the disk.
#define DRBOKEH_LAYER_DISK_ROWS 1
#endif
#if defined(DRBOKEH_LAYER_DISK_ROWS) || defined(DRBOKEH_LAYER_GAUGE)
#define DRBOKEH_LAYER_SPANS 1
#endif

#include "drbokeh.glsl"
#include "spans.glsl"

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
#include "drbokeh_layer_out.glsl"
// source_pa = P / A (vec4), source_sa = (s, alpha): texel buffers too.
layout(set = 0, binding = 7) uniform samplerBuffer source_pa;
layout(set = 0, binding = 8) uniform samplerBuffer source_sa;
layout(std430, set = 0, binding = 9) readonly buffer TileRadii { vec4 tile_radii[]; };
layout(set = 0, binding = 10) uniform samplerBuffer block_prefix;
layout(set = 0, binding = 11) uniform samplerBuffer block_suffix;
layout(set = 0, binding = 12) uniform samplerBuffer block_alpha;
#ifdef DRBOKEH_LAYER_GAUGE
// Texel 0: the constants of the gauge's closed form (closed_form_gauge); then two per segment
// of v = oy / c in [-1, 1]: (interior lo, hi, outer lo, hi) of the unit shape's rows for both
// orientations and for the aperture alone, conservative over the segment and its neighbours
// (aperture_row_table; both in src/camera/aperture_rows.rs). A vignetted polygon or ellipse:
// its base's, then from APERTURE_ROW_EYES the centroid (.xy) of each 16 px tile's clipped base
// (Params::eyes), row-major over the frame's tiles.
layout(set = 0, binding = 13) uniform samplerBuffer aperture_rows;
const int APERTURE_ROW_SEGMENTS = 2048; // APERTURE_ROW_SEGMENTS in src/camera/aperture_rows.rs
const int APERTURE_ROW_EYES = 1 + 2 * APERTURE_ROW_SEGMENTS;
// Relative room for the f32 rounding of the gauge (a few dot products, ~1e-6) and of the
// levels: the interior level shrinks by it, the outer level grows by it.
const float GAUGE_MARGIN = 1.0 / 4096.0;
#include "gauge.glsl"
#endif
#ifdef DRBOKEH_LAYER_KERNEL
// The kernel image's row runs (kernel_run_table in src/camera/kernel_runs.rs): texel 0 = (n,
// first cell), then (first, count) per row set, then runs (u lo, u hi, class) in ascending u,
// then the kernel's cells.
layout(set = 0, binding = 13) uniform samplerBuffer kernel_runs;
const float KERNEL_RUN_FULL = 1.0; // KERNEL_RUN_FULL in src/camera/kernel_runs.rs
const float KERNEL_RUN_ZERO = 2.0;

// Texel 0 of the table, read once per invocation (kernel_setup).
float kernel_n;
int kernel_cells;

void kernel_setup() {
    vec2 table = texelFetch(kernel_runs, 0).xy;
    kernel_n = table.x;
    kernel_cells = int(table.y);
}

// aperture_kernel_sample's operations on the table's cells (each its four corners, zero
// outside the image): a coordinate clamped to [-1, n] reads corners of zeros exactly where
// aperture_kernel_sample returns 0, and inside, the same texels with the same weights. One
// fetch instead of four, and no bounds tests (measured: 9.3 s CPU instead of 11.8 for the
// 1024^2 frame with a 64^2 star; the four fetches, not the tests, were the cost).
float kernel_runs_sample(vec2 uv) {
    float n = kernel_n;
    float fx = clamp((uv.x * 0.5 + 0.5) * n - 0.5, -1.0, n);
    float fy = clamp((uv.y * 0.5 + 0.5) * n - 0.5, -1.0, n);
    float x0 = floor(fx);
    float y0 = floor(fy);
    float tx = fx - x0;
    float ty = fy - y0;
    vec4 corners = texelFetch(kernel_runs, kernel_cells + (int(y0) + 1) * (int(n) + 2) + int(x0) + 1);
    float top = corners.x * (1.0 - tx) + corners.y * tx;
    float bottom = corners.z * (1.0 - tx) + corners.w * tx;
    return top * (1.0 - ty) + bottom * ty;
}
#endif

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
#ifdef DRBOKEH_LAYER_RING
    float ring_blend;   // the ring weight's fade-in at this centre's radius
    float hole_support; // inner r + 1/2: the obstruction's reach
#endif
#ifdef DRBOKEH_LAYER_KERNEL
    float kernel_blend; // the kernel weight's fade-in at this centre's radius
#endif
};

Centre centre_at(int index) {
    float s = texelFetch(source_sa, index).x;
    float alpha = texelFetch(source_sa, index).y;
    float r = abs(s);
#ifdef DRBOKEH_LAYER_RING
    float blend = smoothstep(APERTURE_KERNEL_FADE_START_PX, APERTURE_KERNEL_FADE_END_PX, r);
    return Centre(s, r + 0.5, alpha * (1.0 - smoothstep(0.5, 1.5, r)), vec4(0.0), 0.0, 0.0, blend, pc.aperture.z * r + 0.5);
#elif defined(DRBOKEH_LAYER_KERNEL)
    float blend = smoothstep(APERTURE_KERNEL_FADE_START_PX, APERTURE_KERNEL_FADE_END_PX, r);
    return Centre(s, r + 0.5, alpha * (1.0 - smoothstep(0.5, 1.5, r)), vec4(0.0), 0.0, 0.0, blend);
#else
    return Centre(s, r + 0.5, alpha * (1.0 - smoothstep(0.5, 1.5, r)), vec4(0.0), 0.0, 0.0);
#endif
}

#ifdef DRBOKEH_LAYER_KERNEL
// The kernel image's sample for the centre at offset (o, oy) (source - centre): the kernel at
// x - y, mirrored for a centre nearer than focus (aperture_coords), over its soft disk.
float kernel_sample_for_centre(Centre centre, int o, int oy) {
    vec2 p = vec2(float(o), float(oy));
    return kernel_runs_sample((centre.s > 0.0 ? p : -p) / centre.support);
}
#endif

// One tap of the span path: source (pa = P / A, sa = (s, alpha)) at gauge g_source as the
// source sees the aperture and g_centre as the centre does (one Euclidean gauge on the disk
// path). The source covers the disk of `source_radius` (drbokeh_scatter's coverage radius,
// or in the ring's obstruction pass inner times its CoC, computed once per source by the
// caller); the centre's reaches `centre_support`, times the weights k_source and k_centre (1
// for gauge shapes; see the ring's obstruction pass). `inside` = the offset lies in the
// centre's row span (taps outside add exact zeros). `occlusion` is a constant at each call:
// the occlusion-free loop does not evaluate it.
void span_tap(inout Centre c, vec4 pa, vec2 sa, float g_source, float g_centre, float source_radius, float centre_support, float k_source, float k_centre, bool inside, bool is_self, bool occlusion) {
    float s = smoothstep(0.0, 1.0, source_radius + 0.5 - g_source) * k_source;
    if (occlusion && c.occluder > 0.0 && !is_self) {
        s *= 1.0 - c.occluder * (1.0 - smoothstep(-0.5, 0.0, sa.x - c.s));
    }
    float d = smoothstep(0.0, 1.0, centre_support - g_centre) * k_centre;
    s = inside ? s : 0.0;
    d = inside ? d : 0.0;
    c.cw += pa * s;
    c.vis_sum += sa.y * d;
    c.vis_weight += d;
}

#ifdef DRBOKEH_LAYER_DISK_ROWS
// Largest |ox| with ox^2 + oy^2 < outer^2 within the window row: taps at gauge >= outer add exact
// zeros (both smoothsteps' arguments are <= 0 there: `outer` bounds every support, with a
// margin far above the f32 rounding of the gauges), so rows stop before them. The window
// `h` is an integer and rounds the reach up; for a layer of constant blur this drops the
// outer half pixel of the rim, up to a third of the rim taps.
int outer_half_width_disk(float outer, int h, int oy) {
    if (outer >= float(h + 1)) {
        return row_half_width(h, oy);
    }
    // Inside the window's disk (outer < h + 1): the window row needs no test of its own.
    float room = outer * outer - float(oy * oy);
    return room <= 0.0 ? -1 : int(sqrt(room));
}

// Offsets o (source column - centre column) of window row oy: outside .x..y the taps add exact
// zeros. Interior: taps inside add exactly (P / A, alpha, 1) (see gather_span_run).
ivec2 outer_span(float outer, int h, int oy, int orientation) {
    int half_width = outer_half_width_disk(outer, h, oy);
    return ivec2(-half_width, half_width);
}

ivec2 interior_span(float t, int oy, ivec2 outer, int orientation) {
    int m = interior_half_width_disk(t, float(oy * oy), outer.y);
    return ivec2(-m, m);
}
#endif

#ifdef DRBOKEH_LAYER_GAUGE
// The vignetted disk's rows in closed form: the unit cat's-eye's row at height v is the
// intersection of its two unit disks' rows (centres +-a, gauge_normals[0]), as (interior lo,
// hi, outer lo, hi) like the table (exact rows: both the same); empty (.x > .y) above or below.
// Centrally symmetric, so both orientations share it. The f32 error of the bounds (~1e-7, or
// ~5e-4 of a radius where a row meets a disk's top, sqrt of a rounding) stays below what the
// callers' GAUGE_MARGIN moves them there (about sqrt(2 / 4096) = 0.02 of a radius at a top, 1 / 4096
// elsewhere).
vec4 cats_eye_row(float v) {
    vec2 a = gauge_normals[0];
    float room_upper = 1.0 - (v - a.y) * (v - a.y);
    float room_lower = 1.0 - (v + a.y) * (v + a.y);
    if (room_upper < 0.0 || room_lower < 0.0) {
        return vec4(1.0, -1.0, 1.0, -1.0);
    }
    float lo = max(a.x - sqrt(room_upper), -a.x - sqrt(room_lower));
    float hi = min(a.x + sqrt(room_upper), -a.x + sqrt(room_lower));
    return vec4(lo, hi, lo, hi);
}

// The row table's entry for v (clamped far outside [-1, 1]: an empty row there): (interior lo,
// hi, outer lo, hi) at unit level. Orientation 1 (every source and centre nearer than focus):
// the aperture's own rows; -1 (every one farther): its mirror's, the entry of -v negated;
// 0: both orientations'.
vec4 aperture_table_row(float v, int orientation) {
    float w = orientation < 0 ? -v : v;
    float f = (clamp(w, -2.0, 2.0) + 1.0) * 0.5 * float(APERTURE_ROW_SEGMENTS);
    int segment = int(floor(f));
    if (segment < 0 || segment >= APERTURE_ROW_SEGMENTS) {
        return vec4(1.0, -1.0, 1.0, -1.0);
    }
    vec4 row = texelFetch(aperture_rows, 1 + 2 * segment + (orientation != 0 ? 1 : 0));
    return orientation < 0 ? -row.yxwz : row;
}

// A vignetted base's tile (gauge_setup_rows): the shift s and the centroid c.
vec2 eye_shift;
vec2 eye_centroid;

// The row of a vignetted base's K = ((B ∩ D(s)) - c) ∩ D(0) at height v, as the table's: the
// base's own row (the table's, conservative) at v + c.y intersected with the clipping disk's
// there (closed form, exact), moved by -c.x, and with the unit disk's at v. f32 errors as in
// cats_eye_row.
vec4 eye_row(float v) {
    float w = v + eye_centroid.y;
    float room_clip = 1.0 - (w - eye_shift.y) * (w - eye_shift.y);
    float room_unit = 1.0 - v * v;
    if (room_clip < 0.0 || room_unit < 0.0) {
        return vec4(1.0, -1.0, 1.0, -1.0);
    }
    float half_clip = sqrt(room_clip);
    float half_unit = sqrt(room_unit);
    float lo = max(eye_shift.x - half_clip - eye_centroid.x, -half_unit);
    float hi = min(eye_shift.x + half_clip - eye_centroid.x, half_unit);
    vec4 base = aperture_table_row(w, 1) - eye_centroid.x;
    return vec4(max(base.x, lo), min(base.y, hi), max(base.z, lo), min(base.w, hi));
}

// The aperture's row at v for `orientation` (see aperture_table_row).
vec4 aperture_row(float v, int orientation) {
    if (GAUGE_VIGNETTED) {
        return cats_eye_row(v);
    }
    if (!GAUGE_VIGNETTED_BASE) {
        return aperture_table_row(v, orientation);
    }
    // K is not centrally symmetric: the mirror's row is K's at -v negated, and both
    // orientations take the interior of K ∩ -K and the hull of K ∪ -K (of the non-empty ones).
    vec4 own = eye_row(v);
    if (orientation > 0) {
        return own;
    }
    vec4 mirrored = -eye_row(-v).yxwz;
    if (orientation < 0) {
        return mirrored;
    }
    vec4 both = vec4(max(own.x, mirrored.x), min(own.y, mirrored.y), min(own.z, mirrored.z), max(own.w, mirrored.w));
    if (own.z > own.w) {
        both.zw = mirrored.zw;
    }
    if (mirrored.z > mirrored.w) {
        both.zw = own.zw;
    }
    return both;
}

// Taps at gauge >= outer (in their orientation) add exact zeros (see outer_half_width_disk):
// the table's row at level outer (grown by the rounding margin), clipped to the window row. An
// empty row has .x > .y.
ivec2 outer_span(float outer, int h, int oy, int orientation) {
    int half_width = row_half_width(h, oy);
    if (outer >= float(h + 1)) {
        return ivec2(-half_width, half_width);
    }
    float c = outer * (1.0 + GAUGE_MARGIN) + GAUGE_MARGIN;
    vec4 row = aperture_row(float(oy) / c, orientation);
    return ivec2(max(-half_width, int(floor(c * row.z))), min(half_width, int(ceil(c * row.w))));
}

// Columns where the gauges (in their orientation) are at most t - 1 (level shrunk by the
// margin), so every smoothstep of the tap is exactly 1; within `outer`. Functions of t, oy and
// the tile's orientation alone, so of global positions (bit-identical tiling).
ivec2 interior_span(float t, int oy, ivec2 outer, int orientation) {
    float c = (t - 1.0) * (1.0 - GAUGE_MARGIN);
    if (c <= 0.0) {
        return ivec2(1, 0);
    }
    vec4 row = aperture_row(float(oy) / c, orientation);
    return ivec2(max(outer.x, int(ceil(c * row.x))), min(outer.y, int(floor(c * row.y))));
}

// The gauge's closed-form constants come from the host (texel 0 of aperture_rows), computed
// in f64 like the row table they must agree with. The vignetted disk's from the tile of x0:
// the cat's-eye at the middle of the tile's in-frame part (`LensView::at_receiver`), so the
// whole workgroup shares one shape and closed-form rows (cats_eye_row) instead of a table.
void gauge_setup_rows(ivec2 x0) {
    if (GAUGE_VIGNETTED_BASE) {
        // The base's normals (roundness 0), then the tile's K (Params::receiver_lens).
        ivec2 tile = x0 / DRBOKEH_TILE;
        ivec2 first = tile * DRBOKEH_TILE;
        ivec2 last = min(first + DRBOKEH_TILE - 1, ivec2(pc.width, pc.height) - 1);
        eye_shift = 2.0 * drbokeh_vignette_centre(vec2(first + last) * 0.5);
        eye_centroid = texelFetch(aperture_rows, APERTURE_ROW_EYES + tile.y * pc.tiles_x + tile.x).xy;
        gauge_setup(vec4(0.0), texelFetch(aperture_rows, 0));
        gauge_vignette_setup(eye_shift, eye_centroid);
        return;
    }
    if (GAUGE_VIGNETTED) {
        ivec2 first = x0 / DRBOKEH_TILE * DRBOKEH_TILE;
        ivec2 last = min(first + DRBOKEH_TILE - 1, ivec2(pc.width, pc.height) - 1);
        vec2 a = drbokeh_vignette_centre(vec2(first + last) * 0.5);
        float k = 1.0 - dot(a, a);
        gauge_setup(pc.aperture, vec4(a, 1.0 / k, k));
        return;
    }
    gauge_setup(pc.aperture, texelFetch(aperture_rows, 0));
}

// The gauges of offset (o, oy) (source - centre) as a near source sees it (.x: the offset x - y
// mirrored, aperture_coords) and as a far one does (.y).
vec2 offset_gauges(int o, int oy) {
    return gauge_pair(vec2(float(o), float(oy)));
}
#endif

#ifdef DRBOKEH_LAYER_SPANS
// Full taps of columns [from, to] (offsets from x0) of one window row for all RUN centres, in
// x order: centre k's gauges are the ones centre k - 1 had a column earlier. `span`: the row's
// offsets that may add anything (centre k's tap at column ox has offset ox - k). `hole` (a
// constant at each call; the ring only): the obstruction's taps, subtracted (see main).
// `one_sample` (a constant at each call; the kernel path only): every source with alpha > 0
// has the centres' signed CoC (tile_radii.w), so one kernel sample serves both sides.
void full_taps(inout Centre c[RUN], int row, int from, int to, ivec2 span, int oy, bool occlusion, bool hole, bool one_sample) {
    if (from > to) {
        return;
    }
#ifdef DRBOKEH_LAYER_GAUGE
    vec2 g[RUN]; // g[k] = (near, far) gauges of the current column from centre k
    for (int k = 1; k < RUN; ++k) {
        g[k] = offset_gauges(from - k, oy);
    }
#else
    float oy2 = float(oy * oy);
    float g[RUN]; // g[k] = gauge (Euclidean) of the current column from centre k
    for (int k = 1; k < RUN; ++k) {
        g[k] = sqrt(float((from - k) * (from - k)) + oy2);
    }
#endif
#ifdef DRBOKEH_LAYER_KERNEL
    // With one_sample every centre has one signed CoC, so centre k's kernel sample at a column
    // is the one centre k - 1 had a column earlier, as the gauges: one new sample a column.
    float q[RUN];
    if (one_sample) {
        for (int k = 1; k < RUN; ++k) {
            q[k] = kernel_sample_for_centre(c[k], from - k, oy);
        }
    }
#endif
    for (int ox = from; ox <= to; ++ox) {
        vec4 pa = texelFetch(source_pa, row + ox);
        vec2 sa = texelFetch(source_sa, row + ox).xy;
        float lifted = drbokeh_coverage_radius(abs(sa.x));
#ifdef DRBOKEH_LAYER_GAUGE
        g[0] = offset_gauges(ox, oy);
#else
        g[0] = sqrt(float(ox * ox) + oy2);
#endif
#ifdef DRBOKEH_LAYER_KERNEL
        if (one_sample) {
            q[0] = kernel_sample_for_centre(c[0], ox, oy);
        }
#endif
        for (int k = 0; k < RUN; ++k) {
            int o = ox - k;
            bool inside = o >= span.x && o <= span.y;
#ifdef DRBOKEH_LAYER_GAUGE
            // Sources nearer than focus (s > 0) see the mirrored aperture.
            float g_source = sa.x > 0.0 ? g[k].x : g[k].y;
            float g_centre = c[k].s > 0.0 ? g[k].x : g[k].y;
            span_tap(c[k], pa, sa, g_source, g_centre, lifted, c[k].support, 1.0, 1.0, inside, o == 0 && oy == 0, occlusion);
#elif defined(DRBOKEH_LAYER_RING)
            if (hole) {
                // -blend(r) S(r, g) S(inner r, g), for the source and the centre.
                float r = abs(sa.x);
                float k_source = -smoothstep(APERTURE_KERNEL_FADE_START_PX, APERTURE_KERNEL_FADE_END_PX, r)
                    * smoothstep(0.0, 1.0, lifted + 0.5 - g[k]);
                float k_centre = -c[k].ring_blend * smoothstep(0.0, 1.0, c[k].support - g[k]);
                span_tap(c[k], pa, sa, g[k], g[k], r * pc.aperture.z, c[k].hole_support, k_source, k_centre, inside, o == 0 && oy == 0, occlusion);
            } else {
                span_tap(c[k], pa, sa, g[k], g[k], lifted, c[k].support, 1.0, 1.0, inside, o == 0 && oy == 0, occlusion);
            }
#elif defined(DRBOKEH_LAYER_KERNEL)
            // drbokeh_lens's kernel weight (aperture_kernel_weight) for the source and for the
            // centre: the kernel at x - y mirrored for a near one (aperture_coords), i.e. at
            // (o, oy) or its mirror.
            vec2 p = vec2(float(o), float(oy));
            float r = abs(sa.x);
            float blend = smoothstep(APERTURE_KERNEL_FADE_START_PX, APERTURE_KERNEL_FADE_END_PX, r);
            float q_centre = one_sample ? q[k] : kernel_sample_for_centre(c[k], o, oy);
            // With one_sample a source of alpha > 0 has s = c[k].s, so the same sample bit for
            // bit (r + 1/2 is the centre's support); a source of alpha 0 adds P / A = 0 exactly
            // and its alpha 0 to V, whatever its weight.
            float q_source = one_sample ? q_centre : kernel_runs_sample((sa.x > 0.0 ? p : -p) / (r + 0.5));
            float k_source = 1.0 + (q_source - 1.0) * blend;
            float k_centre = 1.0 + (q_centre - 1.0) * c[k].kernel_blend;
            span_tap(c[k], pa, sa, g[k], g[k], lifted, c[k].support, k_source, k_centre, inside, o == 0 && oy == 0, occlusion);
#else
            span_tap(c[k], pa, sa, g[k], g[k], lifted, c[k].support, 1.0, 1.0, inside, o == 0 && oy == 0, occlusion);
#endif
        }
        for (int k = RUN - 1; k > 0; --k) {
            g[k] = g[k - 1];
#ifdef DRBOKEH_LAYER_KERNEL
            q[k] = q[k - 1];
#endif
        }
    }
}

// Sum of (P / A, alpha) over global columns [a, b] of one read row (`base` + x = read index of
// global column x), from the global 16-px blocks of drbokeh_layer_blocks.comp
// (DRBOKEH_DEFINE_SPAN_SUM says in which order).
#define DRBOKEH_PA_AT(i) texelFetch(source_pa, i)
#define DRBOKEH_ALPHA_AT(i) texelFetch(source_sa, i).y
DRBOKEH_DEFINE_SPAN_SUM(vec4, span_sum_pa, DRBOKEH_PA_AT, DRBOKEH_BLOCK_PREFIX, DRBOKEH_BLOCK_SUFFIX)
DRBOKEH_DEFINE_SPAN_SUM(float, span_sum_alpha, DRBOKEH_ALPHA_AT, DRBOKEH_BLOCK_SCALAR_PREFIX, DRBOKEH_BLOCK_SCALAR_SUFFIX)

void span_sum(int base, int a, int b, out vec4 pa, out float alpha) {
    pa = span_sum_pa(base, a, b);
    alpha = span_sum_alpha(base, a, b);
}

// Adds the span sum of offsets-from-x0 columns [from, to] of one read row to every centre: each
// tap there adds exactly (P / A, alpha, 1) (see gather_span_run); `hole`: subtracts it.
void interior_sum(inout Centre c[RUN], int row, ivec2 x0, int from, int to, bool hole) {
    vec4 pa;
    float alpha;
    span_sum(row - x0.x, x0.x + from, x0.x + to, pa, alpha);
    float count = float(to - from + 1);
    if (hole) {
        pa = -pa;
        alpha = -alpha;
        count = -count;
    }
    for (int k = 0; k < RUN; ++k) {
        c[k].cw += pa;
        c[k].vis_sum += alpha;
        c[k].vis_weight += count;
    }
}


#ifdef DRBOKEH_LAYER_KERNEL
// The row set of the kernel runs that gather row oy crosses (kernel-space height w = oy, or -oy
// mirrored), over the scales c in [t, outer] that its taps sample at (p / (r + 1/2)): the cell
// row, or the pair of adjacent ones, holding every such height, grown by 1e-3 of a cell for
// the f32 rounding; -1 when they are more (then every tap is evaluated) or outside the kernel.
int kernel_row_set(int w, float t, float outer) {
    float n = kernel_n;
    float a = float(w) / t;
    float b = float(w) / outer;
    int j_lo = int(floor((min(a, b) * 0.5 + 0.5) * n - 0.5 - 1.0e-3));
    int j_hi = int(floor((max(a, b) * 0.5 + 0.5) * n - 0.5 + 1.0e-3));
    if (j_lo < -1 || j_hi > int(n) - 1 || j_hi > j_lo + 1) {
        return -1;
    }
    return j_hi == j_lo ? j_lo + 1 : int(n) + 1 + (j_lo + 1);
}

// One gather row of the kernel path without occlusion: columns ox0..ox1 (offsets from x0)
// split into full runs (a span sum, where also the disk's interior `mid` says S = 1 for every
// centre), zero runs (skipped: K is exactly 0 for every source and centre when every radius
// is at least 3/2, blend exactly 1) and the taps between (evaluated). A run's kernel columns
// q = o (or -o mirrored) with q / c inside it for every scale c in [t, outer]; column ox is in
// it for every centre k when ox - k is. `orientation` (tile_radii.z): 1 every source and
// centre near (the kernel at (o, oy)), -1 every one far (its mirror), 0 both: no runs.
void kernel_row(inout Centre c[RUN], int row, ivec2 x0, int ox0, int ox1, ivec2 span, int oy, ivec2 mid, float t, float outer, int orientation, bool one_sample) {
    bool zeros = t - 0.5 >= APERTURE_KERNEL_FADE_END_PX;
    int set = orientation == 0 ? -1 : kernel_row_set(orientation * oy, t, outer);
    int pos = ox0;
    if (set >= 0) {
        vec4 entry = texelFetch(kernel_runs, 1 + set);
        int first = int(entry.x);
        int count = int(entry.y);
        for (int i = 0; i < count; ++i) {
            // Ascending ox: the runs in order, or reversed for the mirror.
            vec4 run = texelFetch(kernel_runs, first + (orientation > 0 ? i : count - 1 - i));
            bool full = run.z == KERNEL_RUN_FULL;
            if (!full && !zeros) {
                continue;
            }
            int q0 = int(ceil(run.x >= 0.0 ? run.x * outer : run.x * t));
            int q1 = int(floor(run.y >= 0.0 ? run.y * t : run.y * outer));
            int a = max((orientation > 0 ? q0 : -q1) + RUN - 1, pos);
            int b = min(orientation > 0 ? q1 : -q0, ox1);
            if (full) {
                a = max(a, mid.x);
                b = min(b, mid.y);
            }
            if (a > b) {
                continue;
            }
            full_taps(c, row, pos, a - 1, span, oy, false, false, one_sample);
            if (full) {
                interior_sum(c, row, x0, a, b, false);
            }
            pos = b + 1;
        }
    }
    full_taps(c, row, pos, ox1, span, oy, false, false, one_sample);
}
#endif

// Default model, gauge aperture (disk, polygon, ellipse): the terms of drbokeh_lens /
// drbokeh_scatter / drbokeh_occlusion with K = 1 and the shape's gauge, for RUN horizontally
// adjacent centres x0 + (k, 0) (same 16x16 tile, same window): each source is loaded once for all of them, and centre k's gauge
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
void gather_span_run(ivec2 x0, int h, float t, float outer, int orientation, inout Centre c[RUN], bool occlusion, bool hole, bool one_sample) {
    int oy0 = max(-h, -x0.y);
    int oy1 = min(h, pc.height - 1 - x0.y);
    for (int oy = oy0; oy <= oy1; ++oy) {
        ivec2 span = outer_span(outer, h, oy, orientation);
        if (span.x > span.y) {
            continue;
        }
        // Offsets from x0: centre k's row is [k + span.x, k + span.y], clipped to the image.
        int ox0 = max(span.x, -x0.x);
        int ox1 = min(span.y + RUN - 1, pc.width - 1 - x0.x);
        int row = drbokeh_read_index(pc.slot, ivec2(x0.x, x0.y + oy));
        // Middle columns [mid0, mid1]: ox - k in the interior span for every centre k.
        int mid0 = ox1 + 1;
        int mid1 = ox1;
        if (!occlusion) {
            ivec2 interior = interior_span(t, oy, span, orientation);
            int a = max(ox0, interior.x + RUN - 1);
            int b = min(ox1, interior.y);
            if (a <= b) {
                mid0 = a;
                mid1 = b;
            }
        }
#ifdef DRBOKEH_LAYER_KERNEL
        if (!occlusion) {
            kernel_row(c, row, x0, ox0, ox1, span, oy, ivec2(mid0, mid1), t, outer, orientation, one_sample);
            continue;
        }
#endif
        full_taps(c, row, ox0, mid0 - 1, span, oy, occlusion, hole, one_sample);
        if (mid0 <= mid1) {
            interior_sum(c, row, x0, mid0, mid1, hole);
        }
        full_taps(c, row, mid1 + 1, ox1, span, oy, occlusion, hole, one_sample);
    }
}
#endif

float visibility(float vis_sum, float vis_weight) {
    return vis_weight > 0.0 ? vis_sum / vis_weight : 0.0;
}


// Any model and aperture: the first kernel's per-tap terms over the clipped window disk.
void gather_general(ivec2 x, int h, out vec4 cw, out float vis) {
    int ix = drbokeh_read_index(pc.slot, x);
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
        int row = drbokeh_read_index(pc.slot, ivec2(x.x, x.y + oy));
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
                float d = drbokeh_footprint(r_x, lens.x) * lens.y;
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
    // A tile this layer adds nothing to leaves the composite as it is: the whole workgroup
    // returns before its loads and stores (one value per workgroup: a true branch).
    if (drbokeh_layer_adds_nothing(h)) {
        return;
    }
    // Centres hidden by the layers in front leave the composite as it is too: a run of them
    // skips its gather (lavapipe runs the lanes of a SIMD row that all return no further).
    bool hidden = true;
    for (int k = 0; k <= last; ++k) {
        hidden = hidden && drbokeh_layer_hidden(x0 + ivec2(k, 0));
    }
    if (hidden) {
        return;
    }
    vec4 cw[RUN];
    float vis[RUN];
#ifdef DRBOKEH_LAYER_SPANS
    {
#ifdef DRBOKEH_LAYER_GAUGE
        gauge_setup_rows(x0);
#endif
#ifdef DRBOKEH_LAYER_KERNEL
        kernel_setup();
#endif
        Centre c[RUN];
        bool occluding = false;
        vec4 radii = tile_radii[tile];
        float t = radii.x + 0.5;
        for (int k = 0; k < RUN; ++k) {
            c[k] = centre_at(drbokeh_read_index(pc.slot, x0 + ivec2(min(k, last), 0)));
            occluding = occluding || c[k].occluder > 0.0;
            t = min(t, c[k].support);
        }
        t = drbokeh_interior_bound(t);
        // Branches are masks on lavapipe: only a lane group with an occluding centre pays for
        // the occlusion terms.
#ifdef DRBOKEH_LAYER_KERNEL
        // One value for the whole workgroup (its 16x16 tile): a true branch.
        bool one_sample = radii.w > 0.5;
        if (occluding) {
            if (one_sample) {
                gather_span_run(x0, h, t, radii.y, int(radii.z), c, true, false, true);
            } else {
                gather_span_run(x0, h, t, radii.y, int(radii.z), c, true, false, false);
            }
        } else if (one_sample) {
            gather_span_run(x0, h, t, radii.y, int(radii.z), c, false, false, true);
        } else {
            gather_span_run(x0, h, t, radii.y, int(radii.z), c, false, false, false);
        }
#else
        if (occluding) {
            gather_span_run(x0, h, t, radii.y, int(radii.z), c, true, false, false);
        } else {
            gather_span_run(x0, h, t, radii.y, int(radii.z), c, false, false, false);
        }
#endif
#ifdef DRBOKEH_LAYER_RING
        // The ring's weight is S(r, g) (1 - blend(r) S(inner r, g)) (aperture_ring_weight: the
        // Hermite step's complement is the step of the reflected argument), so its gather is
        // the disk's less a second gather whose taps weigh blend(r) S(r, g) S(inner r, g): a
        // disk of radius inner r where it lies inside the rim, which has the disk path's
        // interior sums wherever every radius is at least 3/2 (blend exactly 1). Bounds for
        // radius inner r: a lower bound of the radii is t - 1/2, an upper one outer - 1/2.
        float inner = pc.aperture.z;
        float low = t - 0.5;
        float t_hole = low >= APERTURE_KERNEL_FADE_END_PX ? inner * low + 0.5 : 0.0;
        t_hole = drbokeh_interior_bound(t_hole);
        float outer_hole = (inner * (radii.y - 0.5) + 0.5) * (1.0 + 1.0 / 4096.0) + 1.0 / 4096.0;
        int h_hole = outer_hole >= float(h + 1) ? h : int(ceil(outer_hole));
        if (occluding) {
            gather_span_run(x0, h_hole, t_hole, outer_hole, int(radii.z), c, true, true, false);
        } else {
            gather_span_run(x0, h_hole, t_hole, outer_hole, int(radii.z), c, false, true, false);
        }
#endif
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
        int out_index = drbokeh_core_index(pc.slot, x0 + ivec2(k, 0));
        drbokeh_layer_out(out_index, cw[k], vis[k]);
    }
}

#endif
