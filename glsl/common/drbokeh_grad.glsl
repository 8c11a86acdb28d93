// Dr.Bokeh backward: derivatives of the per-term math of drbokeh.glsl, shared by the
// glsl/drbokeh_backward_*.comp passes. Mirrors src/render/drbokeh/math.rs (`d_*`) and
// src/render/drbokeh/backward.rs (`Px`, `pair_grad`, `vis_weight`, `LensView::lens_d`) term
// for term. At a kink of the forward each derivative takes one one-sided value (the backward
// holds every piecewise choice of the forward constant).
#ifndef LENSBLUR_DRBOKEH_GRAD_GLSL
#define LENSBLUR_DRBOKEH_GRAD_GLSL

#include "drbokeh.glsl"

float drbokeh_d_smoothstep(float e0, float e1, float x) {
    float t = (x - e0) / (e1 - e0);
    return (t <= 0.0 || t >= 1.0) ? 0.0 : 6.0 * t * (1.0 - t) / (e1 - e0);
}

float drbokeh_d_scatter(float r, float g) {
    vec2 coverage = drbokeh_coverage_radius_d(r);
    return drbokeh_d_smoothstep(0.0, 1.0, coverage.x + 0.5 - g) * coverage.y;
}

float drbokeh_d_footprint(float r, float g) {
    return drbokeh_d_smoothstep(0.0, 1.0, r + 0.5 - g);
}

float drbokeh_d_area(float r) {
    int last = pc.area_count - 1;
    float r_last = float(last) * pc.area_step;
    if (r >= r_last) {
        return drbokeh_area_lut(last) * 2.0 * r / (r_last * r_last + 0.05);
    }
    float t;
    vec4 p = drbokeh_area_segment(r, 0, t);
    float d_t = 0.5 * (p.z - p.x) + t * (2.0 * p.x - 5.0 * p.y + 4.0 * p.z - p.w) + 1.5 * t * t * (3.0 * (p.y - p.z) + p.w - p.x);
    return d_t / pc.area_step;
}

float drbokeh_d_existence_gate(float w) {
    return drbokeh_d_smoothstep(0.0, 1.0e-3, w);
}

// The compat support keeps a - b > -4, so exp cannot overflow.
float drbokeh_d_softstep(float a, float b) {
    float e = exp(-(a - b) * 3.0);
    float den = 0.1 + e + 1.0e-6;
    return 0.3 * e / (den * den);
}

float drbokeh_d_scatter_compat(float r, float g) {
    return g >= drbokeh_support_compat(r) ? 0.0 : drbokeh_d_softstep(r + 1.0, g);
}

float drbokeh_d_area_compat(float r) {
    return 2.0 * (r + 1.0);
}

// Occlusion partials vec4(d/d src, d/d dst, d/d r_x, d/d alpha_x): src/dst are s_y/s_x
// (default) or rel_y/rel_x (compat), at fixed r_x.
vec4 drbokeh_d_occlusion(float s_y, float s_x, float r_x, float alpha_x, bool is_self) {
    if (is_self) {
        return vec4(0.0);
    }
    float in_focus = 1.0 - smoothstep(0.5, 1.5, r_x);
    float behind = 1.0 - smoothstep(-0.5, 0.0, s_y - s_x);
    float d_behind = -drbokeh_d_smoothstep(-0.5, 0.0, s_y - s_x);
    float d_in_focus = -drbokeh_d_smoothstep(0.5, 1.5, r_x);
    return vec4(-alpha_x * in_focus * d_behind, alpha_x * in_focus * d_behind, -alpha_x * d_in_focus * behind, -in_focus * behind);
}

vec4 drbokeh_d_occlusion_compat(float rel_y, float rel_x, float r_x, bool is_self) {
    if (is_self) {
        return vec4(0.0);
    }
    float gauss = exp(-3.0 * r_x * r_x);
    float z = 10.0 * (rel_y - rel_x - 0.1);
    float th = tanh(clamp(z, -15.0, 15.0));
    float d_rel = abs(z) < 15.0 ? 5.0 * (1.0 - th * th) : 0.0;
    return vec4(gauss * d_rel, -gauss * d_rel, 6.0 * r_x * gauss * (0.5 - 0.5 * th), 0.0);
}

// aperture_kernel_sample and its gradient: vec3(value, d/du, d/dv).
vec3 aperture_kernel_sample_grad(vec2 uv, int size) {
    float n = float(size);
    float fx = (uv.x * 0.5 + 0.5) * n - 0.5;
    float fy = (uv.y * 0.5 + 0.5) * n - 0.5;
    if (!(fx > -1.0 && fy > -1.0 && fx < n && fy < n)) {
        return vec3(0.0);
    }
    float x0 = floor(fx);
    float y0 = floor(fy);
    float tx = fx - x0;
    float ty = fy - y0;
    float a = aperture_kernel_at(x0, y0, size);
    float b = aperture_kernel_at(x0 + 1.0, y0, size);
    float c = aperture_kernel_at(x0, y0 + 1.0, size);
    float d = aperture_kernel_at(x0 + 1.0, y0 + 1.0, size);
    float top = a * (1.0 - tx) + b * tx;
    float bottom = c * (1.0 - tx) + d * tx;
    float d_fx = (b - a) * (1.0 - ty) + (d - c) * ty;
    return vec3(top * (1.0 - ty) + bottom * ty, d_fx * 0.5 * n, (bottom - top) * 0.5 * n);
}

// The ring's weight through a CoC of radius r at gauge g and its d/dr: vec2(K, dK/dr)
// (aperture_ring_weight; LensView::lens_d in src/render/drbokeh/backward.rs).
vec2 drbokeh_ring_weight_d(float g, float r) {
    float inner = pc.aperture.z;
    float arg = g - (inner * r - 0.5);
    float blend = smoothstep(DRBOKEH_KERNEL_FADE_START_PX, DRBOKEH_KERNEL_FADE_END_PX, r);
    float d_blend = drbokeh_d_smoothstep(DRBOKEH_KERNEL_FADE_START_PX, DRBOKEH_KERNEL_FADE_END_PX, r);
    float step = smoothstep(0.0, 1.0, arg);
    return vec2(1.0 - blend * (1.0 - step), -d_blend * (1.0 - step) - blend * drbokeh_d_smoothstep(0.0, 1.0, arg) * inner);
}

// The kernel image's weight at p (aperture coordinates, pixels) through a CoC of radius r and
// its d/dr: vec2(K, dK/dr) (aperture_kernel_weight; the sample at p / (r + 1/2) moves with r).
vec2 drbokeh_kernel_weight_d(vec2 p, float r) {
    float scale = 1.0 / (r + 0.5);
    vec3 sample_grad = aperture_kernel_sample_grad(p * scale, pc.kernel_size);
    float d_sample = -dot(sample_grad.yz, p) * scale * scale;
    float blend = smoothstep(DRBOKEH_KERNEL_FADE_START_PX, DRBOKEH_KERNEL_FADE_END_PX, r);
    float d_blend = drbokeh_d_smoothstep(DRBOKEH_KERNEL_FADE_START_PX, DRBOKEH_KERNEL_FADE_END_PX, r);
    return vec2(1.0 + (sample_grad.x - 1.0) * blend, d_sample * blend + (sample_grad.x - 1.0) * d_blend);
}

// drbokeh_lens plus d(kernel weight)/dr: vec3(gauge, weight, d weight / dr) (the ring's:
// LensView::lens_d in src/render/drbokeh/backward.rs).
vec3 drbokeh_lens_d(vec2 offset, float r, float rel) {
    vec2 p = aperture_coords(offset, rel);
    float g = aperture_gauge(p, pc.aperture);
    if (aperture_is_ring(pc.aperture)) {
        return vec3(g, drbokeh_ring_weight_d(g, r));
    }
    if (pc.aperture.w < 0.5 || pc.kernel_size == 0) {
        return vec3(g, 1.0, 0.0);
    }
    return vec3(g, drbokeh_kernel_weight_d(p, r));
}

// The monotonic leaky slope of the scatter step (pc.leaky_slope = 0: exact).
float drbokeh_leaky(float derivative) {
    return max(derivative, pc.leaky_slope);
}

struct DrBokehPx {
    float rel;
    float s;
    float r;
    float alpha;
};

DrBokehPx drbokeh_px(float disparity, float alpha) {
    float rel = disparity - pc.focus_disparity;
    float s = pc.k_px * rel;
    return DrBokehPx(rel, s, abs(s), alpha);
}

// d|s|/ds, 0 at exact focus.
float drbokeh_sign(float s) {
    return s > 0.0 ? 1.0 : (s < 0.0 ? -1.0 : 0.0);
}

struct DrBokehPairGrad {
    float w;
    float s_y;
    float rel_y;
    float s_x;
    float rel_x;
    float alpha_x;
};

// w = S K O / A of source y at receiver x (offset x - y) and its partials.
DrBokehPairGrad drbokeh_pair_grad(vec2 offset, DrBokehPx src, DrBokehPx dst, bool is_self) {
    vec3 lens = drbokeh_lens_d(offset, src.r, src.rel);
    bool compat = pc.model == DRBOKEH_MODEL_COMPAT;
    float s = compat ? drbokeh_scatter_compat(src.r, lens.x) : drbokeh_scatter(src.r, lens.x);
    float ds = drbokeh_leaky(compat ? drbokeh_d_scatter_compat(src.r, lens.x) : drbokeh_d_scatter(src.r, lens.x));
    float area = drbokeh_area_for(src.r);
    float d_area = compat ? drbokeh_d_area_compat(src.r) : drbokeh_d_area(src.r);
    float o = compat ? drbokeh_occlusion_compat(src.rel, dst.rel, dst.r, is_self)
                     : drbokeh_occlusion(src.s, dst.s, dst.r, dst.alpha, is_self);
    vec4 d_o = compat ? drbokeh_d_occlusion_compat(src.rel, dst.rel, dst.r, is_self)
                      : drbokeh_d_occlusion(src.s, dst.s, dst.r, dst.alpha, is_self);
    float base = s * lens.y / area;
    float d_r_y = ((ds * lens.y + s * lens.z) - s * lens.y * d_area / area) * o / area;
    float d_receiver = base * d_o.z * drbokeh_sign(dst.s);
    if (compat) {
        return DrBokehPairGrad(base * o, d_r_y * drbokeh_sign(src.s), base * d_o.x, d_receiver, base * d_o.y, 0.0);
    }
    return DrBokehPairGrad(base * o, d_r_y * drbokeh_sign(src.s) + base * d_o.x, 0.0, base * d_o.y + d_receiver, 0.0, base * d_o.w);
}

// Default model: whether receiver x can occlude a source (O(y, x) < 1 or dO != 0 for some y).
// At r_x >= 1.5 the in-focus factor 1 - smoothstep(0.5, 1.5, r_x) and its slope are exact 0.
bool drbokeh_occludes(DrBokehPx dst) {
    return dst.r < 1.5;
}

// Squared Euclidean offset length from which a step of support `support` (scatter, V) and its
// slope are exact zeros: every aperture gauge is at least the Euclidean length, so such taps
// have g >= support. The relative margin covers f32 rounding of the gauge (polygon cos
// included); taps inside it that the reference would also visit just add exact zeros.
float drbokeh_zero_beyond2(float support) {
    float limit = support * (1.0 + 1.0 / 4096.0);
    return limit * limit;
}

// Half-width of row oy of a window of half-width h, clipped to the offsets with
// float(ox^2 + oy^2) < limit2 (the whole row for a huge limit2); -1 when the row is empty.
int drbokeh_clipped_half_width(int h, int oy, float limit2) {
    float room = limit2 - float(oy * oy);
    if (!(room > 0.0)) {
        return -1;
    }
    int m = int(min(float(h), floor(sqrt(room))));
    // The estimate is off by a rounding at most: settle it with the exact test.
    while (m >= 0 && float(m * m + oy * oy) >= limit2) {
        m -= 1;
    }
    while (m < h && float((m + 1) * (m + 1) + oy * oy) < limit2) {
        m += 1;
    }
    return m;
}

// Default-model visibility weight D = F(r_x, g) K of offset x - y (F the receiver's footprint),
// and dD/dr_x.
vec2 drbokeh_vis_weight(vec2 offset, DrBokehPx dst) {
    vec3 lens = drbokeh_lens_d(offset, dst.r, dst.rel);
    float s = drbokeh_footprint(dst.r, lens.x);
    return vec2(s * lens.y, drbokeh_leaky(drbokeh_d_footprint(dst.r, lens.x)) * lens.y + s * lens.z);
}

#endif
