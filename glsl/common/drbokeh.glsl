// Dr.Bokeh forward renderer: push constants and per-term math shared by the
// glsl/drbokeh_*.comp passes. Mirrors src/render/drbokeh/math.rs (f64) term for term; the
// push block mirrors `DrBokehPush` in src/render/drbokeh/mod.rs (112 bytes).
//
// Units: r = CoC radius in pixels, s = signed CoC radius (positive = nearer than focus),
// g = aperture gauge of an offset in pixels, rel = relative disparity d - d_f.
// A shader that calls `drbokeh_area` must define  float drbokeh_area_lut(int index);
#ifndef LENSBLUR_DRBOKEH_GLSL
#define LENSBLUR_DRBOKEH_GLSL

#include "aperture.glsl"

const int DRBOKEH_TILE = 16;
const int DRBOKEH_MODEL_DRBOKEH = 0;
const int DRBOKEH_MODEL_COMPAT = 1;
const float DRBOKEH_COMPAT_TAIL_PX = 4.0;
const float DRBOKEH_KERNEL_FADE_START_PX = APERTURE_KERNEL_FADE_START_PX;
const float DRBOKEH_KERNEL_FADE_END_PX = APERTURE_KERNEL_FADE_END_PX;

layout(push_constant) uniform DrBokehPush {
    int width;            // 0
    int height;           // 4
    int tiles_x;          // 8
    int tiles_y;          // 12
    int layer;            // 16  layer of this dispatch (0 = front)
    int layer_count;      // 20
    int model;            // 24  DRBOKEH_MODEL_*
    int kernel_size;      // 28  side of the kernel buffer, 0 = none
    float k_px;           // 32  CoC pixels per unit disparity
    float focus_disparity;// 36
    float max_support;    // 40  largest support / gather radius in the stack (px)
    float area_step;      // 44  px of radius per area-table entry
    int area_count;       // 48  entries in the area table
    float leaky_slope;    // 52  backward passes only: smallest scatter slope (0 = exact)
    int slot;             // 56  layer's place in this dispatch's per-layer buffers: pc.layer
                          //     where they hold every layer, 0 where they hold one
    int fold;             // 60  layer passes: 1 = fold (C, W, V) into the running composite
                          //     held in bindings 5 (vec4) and 6 (transmittance), layer 0
                          //     starting it; 0 = write them there
    vec4 aperture;        // 64  Aperture::gpu_params
    ivec4 core;           // 80  frame tile written: x, y, width, height (outputs core-local)
    ivec4 read;           // 96  uploaded rect: x, y, width, height (sources read-local)
} pc;

float drbokeh_area_lut(int index);

bool drbokeh_inside(ivec2 p) {
    return p.x >= 0 && p.y >= 0 && p.x < pc.width && p.y < pc.height;
}

// Image pixel of this invocation in a (core-width x core-height) dispatch; (-1, -1) outside.
ivec2 drbokeh_core_pixel(uvec3 id) {
    ivec2 local = ivec2(id.xy);
    if (local.x >= pc.core.z || local.y >= pc.core.w) {
        return ivec2(-1);
    }
    return pc.core.xy + local;
}

// Index of image pixel p in a core-sized per-pixel buffer of layer l.
int drbokeh_core_index(int l, ivec2 p) {
    ivec2 q = p - pc.core.xy;
    return (l * pc.core.w + q.y) * pc.core.z + q.x;
}

// Index of image pixel p in a read-rect-sized source buffer of layer l.
int drbokeh_read_index(int l, ivec2 p) {
    ivec2 q = p - pc.read.xy;
    return (l * pc.read.w + q.y) * pc.read.z + q.x;
}

// ---------------------------------------------------------------- default model

// math::coverage_radius: the radius of the disk a source of CoC radius r scatters, chosen so that
// its lattice weights blur as much as the lens (variance r^2 / 4 per axis): lifted under 0.7
// px, dipped below r over 0.7-2.65 px (math::DIPS), r itself beyond; increasing. The layer pass
// evaluates it for every source of its rim taps, so it is written without branches: for the
// lift, v = max(u + softness, 0) with u = LIFT_AT_ZERO - LIFT_SLOPE r, the lift being
// v^2 / (4 softness) up to v = 2 softness, then u (math::lift's three pieces); each dip is a
// product of two clamped Hermite ramps.
const float DRBOKEH_LIFT_AT_ZERO = 0.5;
const float DRBOKEH_LIFT_SLOPE = 0.77;
const float DRBOKEH_LIFT_SOFTNESS = 0.03;
// Per dip: (rise from, rise width, fall from, fall width); heights apart.
const vec4 DRBOKEH_DIP_0 = vec4(0.605, 0.415, 1.393, 0.245);
const vec4 DRBOKEH_DIP_1 = vec4(1.778, 0.477, 2.331, 0.317);
const vec2 DRBOKEH_DIP_HEIGHTS = vec2(0.181, 0.121);

// The coverage radius (x) and its slope in r (y); callers of the radius alone leave y unused.
vec2 drbokeh_coverage_radius_d(float r) {
    float v = max(DRBOKEH_LIFT_AT_ZERO + DRBOKEH_LIFT_SOFTNESS - DRBOKEH_LIFT_SLOPE * r, 0.0);
    bool parabola = v <= 2.0 * DRBOKEH_LIFT_SOFTNESS;
    float lift = parabola ? v * v * (0.25 / DRBOKEH_LIFT_SOFTNESS) : v - DRBOKEH_LIFT_SOFTNESS;
    float d_lift = parabola ? v * (0.5 / DRBOKEH_LIFT_SOFTNESS) : 1.0;
    // The dips' four ramps: (rise 0, fall 0, rise 1, fall 1).
    vec4 width = vec4(DRBOKEH_DIP_0.yw, DRBOKEH_DIP_1.yw);
    vec4 t = clamp((vec4(r) - vec4(DRBOKEH_DIP_0.xz, DRBOKEH_DIP_1.xz)) / width, 0.0, 1.0);
    vec4 ramp = t * t * (3.0 - 2.0 * t);
    vec4 d_ramp = 6.0 * t * (1.0 - t) / width;
    vec2 dip = DRBOKEH_DIP_HEIGHTS * ramp.xz * (1.0 - ramp.yw);
    vec2 d_dip = DRBOKEH_DIP_HEIGHTS * (d_ramp.xz * (1.0 - ramp.yw) - ramp.xz * d_ramp.yw);
    return vec2(r + lift - dip.x - dip.y, 1.0 - DRBOKEH_LIFT_SLOPE * d_lift - d_dip.x - d_dip.y);
}

float drbokeh_coverage_radius(float r) {
    return drbokeh_coverage_radius_d(r).x;
}

// Hermite-rimmed coverage of the disk of drbokeh_coverage_radius(r): exactly 0 for
// g >= drbokeh_support(r); a source with r = 0 reaches only its own pixel.
float drbokeh_scatter(float r, float g) {
    return smoothstep(0.0, 1.0, drbokeh_coverage_radius(r) + 0.5 - g);
}

// The receiver's footprint in V: the Hermite ramp at its own radius, not lifted
// (math::footprint says why).
float drbokeh_footprint(float r, float g) {
    return smoothstep(0.0, 1.0, r + 0.5 - g);
}

// Reach of a pixel of CoC radius r: of drbokeh_scatter (a source's) and of drbokeh_footprint
// (a receiver's), the larger (math::support).
float drbokeh_support(float r) {
    return max(drbokeh_coverage_radius(r), r) + 0.5;
}

// Reach of drbokeh_footprint alone (a receiver's in V): its own radius, not the coverage one.
float drbokeh_footprint_support(float r) {
    return r + 0.5;
}

// In-layer occlusion in CoC pixels: an (almost) in-focus, present x blocks a y behind it.
float drbokeh_occlusion(float s_y, float s_x, float r_x, float alpha_x, bool is_self) {
    if (is_self) {
        return 1.0;
    }
    float in_focus = 1.0 - smoothstep(0.5, 1.5, r_x);
    float behind = 1.0 - smoothstep(-0.5, 0.0, s_y - s_x);
    return 1.0 - alpha_x * in_focus * behind;
}

// Area normalisation: exact lattice sums tabulated on the host, a Catmull-Rom spline through
// the entries (math::area_from_lut says why), then the r^2 + 1/20 growth of the continuous
// integral. `level`: which of a vignetted lens's tables (0 otherwise).
// The four entries around r's segment of table `level` (the ends extended in a straight line),
// and r's place t in it: (p0, p1, p2, p3), t.
vec4 drbokeh_area_segment(float r, int level, out float t) {
    int base = level * pc.area_count;
    int last = pc.area_count - 1;
    float f = r / pc.area_step;
    int i = min(int(floor(f)), last - 1);
    t = f - float(i);
    float p1 = drbokeh_area_lut(base + i);
    float p2 = drbokeh_area_lut(base + i + 1);
    float p0 = i > 0 ? drbokeh_area_lut(base + i - 1) : 2.0 * p1 - p2;
    float p3 = i + 2 <= last ? drbokeh_area_lut(base + i + 2) : 2.0 * p2 - p1;
    return vec4(p0, p1, p2, p3);
}

float drbokeh_area_in(float r, int level) {
    int last = pc.area_count - 1;
    float r_last = float(last) * pc.area_step;
    if (r >= r_last) {
        return drbokeh_area_lut(level * pc.area_count + last) * (r * r + 0.05) / (r_last * r_last + 0.05);
    }
    float t;
    vec4 p = drbokeh_area_segment(r, level, t);
    return p.y + 0.5 * t * (p.z - p.x + t * (2.0 * p.x - 5.0 * p.y + 4.0 * p.z - p.w + t * (3.0 * (p.y - p.z) + p.w - p.x)));
}

float drbokeh_area(float r) {
    return drbokeh_area_in(r, 0);
}

// The vignetted disk (shape -2, strength pc.aperture.y): its cat's-eye centre a at frame
// position p (disks at +-a), half of character::CatsEye::shift. `LensView::vignette_centre`.
const int DRBOKEH_VIGNETTE_AREA_LEVELS = 17; // VIGNETTE_AREA_LEVELS in src/render/drbokeh/mod.rs

vec2 drbokeh_vignette_centre(vec2 p) {
    vec2 c = vec2(float(pc.width - 1), float(pc.height - 1)) * 0.5;
    return (0.5 * pc.aperture.y / max(length(c), 1.0)) * (p - c);
}

const int DRBOKEH_VIGNETTE_BASE_AREA_LEVELS = 9; // VIGNETTE_BASE_AREA_LEVELS in src/render/drbokeh/mod.rs
const int DRBOKEH_VIGNETTE_AREA_DIRECTIONS = 9; // VIGNETTE_AREA_DIRECTIONS
const float DRBOKEH_PI = 3.14159265358979;

// Area of a source of radius r at pixel p of a vignetted render: linear between the area
// tables of the two cat's-eyes around its |a| (`Params::area_at`). A vignetted polygon or
// ellipse (base shape pc.aperture.z, rotation .w): bilinear in |s| and the shift's direction
// folded into half a symmetry sector (`vignette_area_coordinates`).
float drbokeh_area_at(float r, ivec2 p) {
    if (pc.aperture.z > 0.5) {
        vec2 s = 2.0 * drbokeh_vignette_centre(vec2(p));
        float len = length(s);
        float level = pc.aperture.y > 0.0 ? len / pc.aperture.y * float(DRBOKEH_VIGNETTE_BASE_AREA_LEVELS - 1) : 0.0;
        float sector = 2.0 * DRBOKEH_PI / (pc.aperture.z >= 3.0 ? pc.aperture.z : 2.0);
        float angle = len > 0.0 ? mod(atan(s.y, s.x) - pc.aperture.w, sector) : 0.0;
        float folded = clamp(min(angle, sector - angle), 0.0, 0.5 * sector);
        float direction = folded / (0.5 * sector) * float(DRBOKEH_VIGNETTE_AREA_DIRECTIONS - 1);
        int l = min(int(floor(level)), DRBOKEH_VIGNETTE_BASE_AREA_LEVELS - 2);
        int d = min(int(floor(direction)), DRBOKEH_VIGNETTE_AREA_DIRECTIONS - 2);
        float tl = level - float(l);
        float td = direction - float(d);
        int at = l * DRBOKEH_VIGNETTE_AREA_DIRECTIONS + d;
        float near = drbokeh_area_in(r, at) * (1.0 - td) + drbokeh_area_in(r, at + 1) * td;
        at += DRBOKEH_VIGNETTE_AREA_DIRECTIONS;
        float far = drbokeh_area_in(r, at) * (1.0 - td) + drbokeh_area_in(r, at + 1) * td;
        return near * (1.0 - tl) + far * tl;
    }
    float top = 0.5 * pc.aperture.y;
    float f = top > 0.0 ? length(drbokeh_vignette_centre(vec2(p))) / top * float(DRBOKEH_VIGNETTE_AREA_LEVELS - 1) : 0.0;
    int level = min(int(floor(f)), DRBOKEH_VIGNETTE_AREA_LEVELS - 2);
    float t = f - float(level);
    return drbokeh_area_in(r, level) * (1.0 - t) + drbokeh_area_in(r, level + 1) * t;
}

// Drops the coverage V claims where no source of the layer reaches x (W = 0).
float drbokeh_existence_gate(float w) {
    return smoothstep(0.0, 1.0e-3, w);
}

// One layer's step of the front-to-back composite B = sum_l V_l prod_{k<l} (1 - V_k) C_l / W_l,
// alpha = sum_l V_l prod_{k<l} (1 - V_k): `outp` and `transmittance` hold the layers in front;
// the default model gates V by the layer's existence (W > 0). glsl/drbokeh_composite.comp runs it
// over every layer; a forward render layer by layer (`pc.fold`) runs it at the end of each
// layer's pass. CPU reference: src/render/drbokeh/cpu.rs `composite_pixel`.
void drbokeh_composite_step(inout vec4 outp, inout float transmittance, vec4 cw, float v) {
    if (pc.model == DRBOKEH_MODEL_DRBOKEH) {
        v *= drbokeh_existence_gate(cw.w);
    }
    vec3 colour = cw.w > 0.0 ? cw.xyz / cw.w : vec3(0.0);
    outp.xyz += transmittance * v * colour;
    outp.w += transmittance * v;
    transmittance *= 1.0 - v;
}

// ---------------------------------------------------------------- compat model (released)

float drbokeh_softstep(float a, float b) {
    return 0.1 / (0.1 + exp(-(a - b) * 3.0) + 1.0e-6);
}

float drbokeh_support_compat(float r) {
    return r + 1.0 + DRBOKEH_COMPAT_TAIL_PX;
}

float drbokeh_scatter_compat(float r, float g) {
    return g >= drbokeh_support_compat(r) ? 0.0 : drbokeh_softstep(r + 1.0, g);
}

float drbokeh_area_compat(float r) {
    return (r + 1.0) * (r + 1.0);
}

// Released constants 10 and 0.1 are in disparity units, applied to relative disparities.
float drbokeh_occlusion_compat(float rel_y, float rel_x, float r_x, bool is_self) {
    if (is_self) {
        return 1.0;
    }
    float in_focal = 1.0 - exp(-3.0 * r_x * r_x);
    float rel = 0.5 + 0.5 * tanh(clamp(10.0 * (rel_y - rel_x - 0.1), -15.0, 15.0));
    return (1.0 - in_focal) * rel + in_focal;
}

int drbokeh_visibility_box_compat(float r_x) {
    return int(floor((r_x + 1.0) * 0.5));
}

// ---------------------------------------------------------------- shared

float drbokeh_support_for(float r) {
    return pc.model == DRBOKEH_MODEL_COMPAT ? drbokeh_support_compat(r) : drbokeh_support(r);
}

float drbokeh_area_for(float r) {
    return pc.model == DRBOKEH_MODEL_COMPAT ? drbokeh_area_compat(r) : drbokeh_area(r);
}

// Gauge (x) and kernel weight (y) of the offset x - y seen through a CoC of radius r at
// relative disparity rel. Kernel weights fade in over 0.5..1.5 px (sub-pixel kernels
// integrate to a point); the kernel covers the soft disk of radius r + 1/2.
vec2 drbokeh_lens(vec2 offset, float r, float rel) {
    vec2 p = aperture_coords(offset, rel);
    return vec2(aperture_gauge(p, pc.aperture), aperture_kernel_weight(p, r, pc.aperture, pc.kernel_size));
}

#endif
