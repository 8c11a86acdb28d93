// Closed-form gauges of the polygon and ellipse apertures, without atan or cos per tap, for
// the passes that evaluate them at many taps (the layer pass's gauge path, the backward
// passes' gauge paths). The same function as aperture_gauge (glsl/common/aperture.glsl), up
// to f32 rounding:
// - a polygon's gauge is max_i p . n_i over its edge normals n_i scaled by 1 / cos(pi / n)
//   (the nearest normal gives len * cos(folded)), blended toward len by roundness; the
//   mirrored aperture's (a near source's) is max_i -p . n_i = -min_i p . n_i, from the same
//   products. An even polygon is symmetric: half its normals, |p . n_i|. The normals are
//   stepped by the sector's rotation rather than kept in an array: a private array indexed in
//   a loop is memory on lavapipe, the rotation stays in registers.
// - an ellipse's is |(p . a, p . b)| with a, b its axes scaled by 1 and the squeeze.
// Constants: `closed_form_gauge` in src/camera/aperture_rows.rs (f64), or gauge_constants
// below (in the shader's f32) where no table carries them.
#ifndef LENSBLUR_GAUGE_GLSL
#define LENSBLUR_GAUGE_GLSL

#include "aperture.glsl"

vec2 gauge_first;  // polygon: first edge normal / cos(pi / n); ellipse: its long axis
vec2 gauge_second; // polygon: (cos, sin) of the sector angle; ellipse: short axis * squeeze
int gauge_steps;   // polygon: normals visited (n, or n / 2 when even); 0: the ellipse
bool gauge_even;
float gauge_roundness;

// `closed_form_gauge` of Aperture::gpu_params (shape, rotation, roundness or squeeze, kernel).
vec4 gauge_constants(vec4 aperture) {
    if (aperture.x < 1.5) {
        float c = cos(aperture.y);
        float s = sin(aperture.y);
        return vec4(c, s, -s * aperture.z, c * aperture.z);
    }
    float sector = 2.0 * APERTURE_PI / aperture.x;
    vec2 first = vec2(cos(aperture.y), sin(aperture.y)) / cos(APERTURE_PI / aperture.x);
    return vec4(first, cos(sector), sin(sector));
}

// Once per invocation, before any gauge below.
void gauge_setup(vec4 aperture, vec4 constants) {
    gauge_first = constants.xy;
    gauge_second = constants.zw;
    int blades = int(aperture.x);
    gauge_even = blades % 2 == 0;
    gauge_steps = blades < 3 ? 0 : (gauge_even ? blades / 2 : blades);
    gauge_roundness = blades < 3 ? 0.0 : aperture.z;
}

vec2 gauge_rotate(vec2 normal) {
    return vec2(normal.x * gauge_second.x - normal.y * gauge_second.y, normal.x * gauge_second.y + normal.y * gauge_second.x);
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
    if (gauge_steps == 0) {
        return vec2(length(vec2(dot(p, gauge_first), dot(p, gauge_second))));
    }
    vec2 normal = gauge_first;
    float most = -1.0e30;
    float least = 1.0e30;
    for (int i = 0; i < gauge_steps; ++i) {
        float d = dot(p, normal);
        most = max(most, d);
        least = min(least, d);
        normal = gauge_rotate(normal);
    }
    return gauge_round(gauge_even ? vec2(max(most, -least)) : vec2(most, -least), p);
}

#endif
