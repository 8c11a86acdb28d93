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
//   k = 1 - |a|^2, the same for p and -p;
// - a vignetted polygon's or ellipse's (GAUGE_VIGNETTED_BASE: K = ((B ∩ D(s)) - c) ∩ D(0), the
//   base clipped by the unit disk at the tile's shift s, recentred on the centroid c, cut to
//   the unit disk; src/camera/vignetted.rs) is the largest of three gauges: the base moved by
//   -c (a polygon's normals over 1 - n_i . c, gauge_vignette_setup; the ellipse's the disk
//   formula below in q = M p), the unit disk centred at e = s - c, (-p . e + sqrt((p . e)^2 +
//   k |p|^2)) / k with k = 1 - |e|^2, and |p|. K is not centrally symmetric: p and -p differ.
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
// A vignetted polygon (GAUGE_BLADES its blades) or ellipse (GAUGE_BLADES 0), its shape per
// receiver tile: `LensView::gauge_specialization`'s second constant.
layout(constant_id = 1) const bool GAUGE_VIGNETTED_BASE = false;
// Normals visited: n, or n / 2 for an even polygon (|p . n_i|) unless vignetted (its normals
// are scaled each by its own 1 / (1 - n_i . c)); 0 for the ellipse.
const int GAUGE_STEPS = GAUGE_BLADES < 3 ? 0 : (GAUGE_EVEN && !GAUGE_VIGNETTED_BASE ? GAUGE_BLADES / 2 : GAUGE_BLADES);
const int GAUGE_MAX_STEPS = 16; // Aperture::polygon's limit

// Polygon: edge normals / cos(pi / n); ellipse: [0], [1] its axes; cat's-eye: [0] = a,
// [1] = (1 / k, k).
vec2 gauge_normals[GAUGE_MAX_STEPS];
float gauge_roundness;
// A vignetted base's tile: the clipping disk's centre e = s - c and (1 / k, k), k = 1 - |e|^2;
// the ellipse's -M c and its (1 / k, k) (gauge_vignette_setup).
vec2 gauge_clip_centre;
vec2 gauge_clip_k;
vec2 gauge_base_centre;
vec2 gauge_base_k;

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

// A vignetted base at one tile, after gauge_setup: the shift s and the centroid c of B ∩ D(s).
// `Eye::new` in src/camera/vignetted.rs.
void gauge_vignette_setup(vec2 s, vec2 c) {
    vec2 e = s - c;
    float k = 1.0 - dot(e, e);
    gauge_clip_centre = e;
    gauge_clip_k = vec2(1.0 / k, k);
    if (GAUGE_STEPS == 0) {
        vec2 mc = vec2(dot(gauge_normals[0], c), dot(gauge_normals[1], c));
        float kb = 1.0 - dot(mc, mc);
        gauge_base_centre = -mc;
        gauge_base_k = vec2(1.0 / kb, kb);
        return;
    }
    for (int i = 0; i < GAUGE_STEPS; ++i) {
        gauge_normals[i] /= 1.0 - dot(gauge_normals[i], c);
    }
}

// (G(p), G(-p)) of the unit disk centred at `centre`, k = (1 / k, k) with k = 1 - |centre|^2.
vec2 gauge_disk_pair(vec2 p, vec2 centre, vec2 k) {
    float pe = dot(p, centre);
    float root = sqrt(pe * pe + k.y * dot(p, p));
    return vec2(root - pe, root + pe) * k.x;
}

vec2 gauge_round(vec2 poly, vec2 p) {
    if (gauge_roundness > 0.0) {
        poly += (vec2(length(p)) - poly) * gauge_roundness;
    }
    return poly;
}

// (G(p), G(-p)): the aperture's gauge of p and its mirror's (aperture_coords mirrors the
// aperture for sources nearer than focus).
// (max_i p . n_i, -min_i p . n_i) over the normals visited: a polygon's gauge of p and of -p.
vec2 gauge_polygon_pair(vec2 p) {
    float most = -1.0e30;
    float least = 1.0e30;
    for (int i = 0; i < GAUGE_STEPS; ++i) {
        float d = dot(p, gauge_normals[i]);
        most = max(most, d);
        least = min(least, d);
    }
    return vec2(most, -least);
}

vec2 gauge_pair(vec2 p) {
    if (GAUGE_CATS_EYE) {
        float q = abs(dot(p, gauge_normals[0]));
        return vec2((q + sqrt(q * q + gauge_normals[1].y * dot(p, p))) * gauge_normals[1].x);
    }
    if (GAUGE_VIGNETTED_BASE) {
        vec2 g = max(gauge_disk_pair(p, gauge_clip_centre, gauge_clip_k), vec2(length(p)));
        if (GAUGE_STEPS == 0) {
            vec2 q = vec2(dot(p, gauge_normals[0]), dot(p, gauge_normals[1]));
            return max(g, gauge_disk_pair(q, gauge_base_centre, gauge_base_k));
        }
        return max(g, gauge_polygon_pair(p));
    }
    if (GAUGE_STEPS == 0) {
        return vec2(length(vec2(dot(p, gauge_normals[0]), dot(p, gauge_normals[1]))));
    }
    vec2 pair = gauge_polygon_pair(p);
    return gauge_round(GAUGE_EVEN ? vec2(max(pair.x, pair.y)) : pair, p);
}

#endif
