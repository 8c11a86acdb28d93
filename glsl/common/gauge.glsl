// Closed-form gauges of the polygon and ellipse apertures, without atan or cos per tap, for
// the passes that evaluate them at many taps (the layer pass's gauge path, the backward
// passes' gauge paths). The same function as aperture_gauge (glsl/common/aperture.glsl), up
// to f32 rounding:
// - a polygon's gauge is max_i p . n_i over its edge normals n_i scaled by 1 / cos(pi / n)
//   (the nearest normal gives len * cos(folded)), blended toward len by roundness; the
//   mirrored aperture's (a near source's) is max_i -p . n_i = -min_i p . n_i, from the same
//   products. An even polygon is symmetric: half its normals, |p . n_i|.
// - an ellipse's is |(p . a, p . b)| with a, b its axes scaled by 1 and the squeeze;
// - a cat's-eye's (the unit disks at +-a) is (|p . a| + sqrt((p . a)^2 + k |p|^2)) / k with
//   k = 1 - |a|^2, the same for p and -p.
// Constants: `closed_form_gauge` in src/camera/aperture_rows.rs (f64), or gauge_constants
// below (in the shader's f32) where no table carries them; the shape itself is a
// specialization constant (`LensView::gauge_specialization` in src/render/drbokeh/mod.rs).
#ifndef LENSBLUR_GAUGE_GLSL
#define LENSBLUR_GAUGE_GLSL

#include "aperture.glsl"

// The shape, a specialization constant (ComputePipeline::specialized): 0 = ellipse, 1 =
// cat's-eye, 2 = the vignetted disk (a cat's-eye whose a the layer pass sets per receiver
// tile), else the polygon's blades. As a literal the loops over the normals unroll and the normals stay in
// registers (a loop with a run-time bound is ~1.5x slower on lavapipe).
layout(constant_id = 0) const int GAUGE_BLADES = 6;
const bool GAUGE_EVEN = GAUGE_BLADES % 2 == 0;
const bool GAUGE_VIGNETTED = GAUGE_BLADES == 2;
const bool GAUGE_CATS_EYE = GAUGE_BLADES == 1 || GAUGE_VIGNETTED;
// Normals visited: n, or n / 2 for an even polygon (|p . n_i|); 0 for the ellipse.
const int GAUGE_STEPS = GAUGE_BLADES < 3 ? 0 : (GAUGE_EVEN ? GAUGE_BLADES / 2 : GAUGE_BLADES);
const int GAUGE_MAX_STEPS = 16; // Aperture::polygon's limit

// Polygon: edge normals / cos(pi / n); ellipse: [0], [1] its axes; cat's-eye: [0] = a,
// [1] = (1 / k, k).
vec2 gauge_normals[GAUGE_MAX_STEPS];
float gauge_roundness;

// `closed_form_gauge` of Aperture::gpu_params (shape, rotation, roundness or squeeze, kernel).
vec4 gauge_constants(vec4 aperture) {
    if (aperture.x < -0.5) {
        float k = 1.0 - dot(aperture.yz, aperture.yz);
        return vec4(aperture.yz, 1.0 / k, k);
    }
    if (aperture.x < 1.5) {
        float c = cos(aperture.y);
        float s = sin(aperture.y);
        return vec4(c, s, -s * aperture.z, c * aperture.z);
    }
    float sector = 2.0 * APERTURE_PI / aperture.x;
    vec2 first = vec2(cos(aperture.y), sin(aperture.y)) / cos(APERTURE_PI / aperture.x);
    return vec4(first, cos(sector), sin(sector));
}

// Once per invocation, before any gauge below: the normals from the first one and the sector's
// rotation (constants.zw).
void gauge_setup(vec4 aperture, vec4 constants) {
    gauge_roundness = GAUGE_STEPS == 0 ? 0.0 : aperture.z;
    if (GAUGE_STEPS == 0) {
        gauge_normals[0] = constants.xy;
        gauge_normals[1] = constants.zw;
        return;
    }
    vec2 normal = constants.xy;
    for (int i = 0; i < GAUGE_STEPS; ++i) {
        gauge_normals[i] = normal;
        normal = vec2(normal.x * constants.z - normal.y * constants.w, normal.x * constants.w + normal.y * constants.z);
    }
}

vec2 gauge_round(vec2 poly, vec2 p) {
    if (gauge_roundness > 0.0) {
        poly += (vec2(length(p)) - poly) * gauge_roundness;
    }
    return poly;
}

// (G(p), G(-p)): the aperture's gauge of p and its mirror's (aperture_coords mirrors the
// aperture for sources nearer than focus).
vec2 gauge_pair(vec2 p) {
    if (GAUGE_CATS_EYE) {
        float q = abs(dot(p, gauge_normals[0]));
        return vec2((q + sqrt(q * q + gauge_normals[1].y * dot(p, p))) * gauge_normals[1].x);
    }
    if (GAUGE_STEPS == 0) {
        return vec2(length(vec2(dot(p, gauge_normals[0]), dot(p, gauge_normals[1]))));
    }
    float most = -1.0e30;
    float least = 1.0e30;
    for (int i = 0; i < GAUGE_STEPS; ++i) {
        float d = dot(p, gauge_normals[i]);
        most = max(most, d);
        least = min(least, d);
    }
    return gauge_round(GAUGE_EVEN ? vec2(max(most, -least)) : vec2(most, -least), p);
}

#endif
