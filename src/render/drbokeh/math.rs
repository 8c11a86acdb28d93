//! The per-term math of the Dr.Bokeh forward renderer in f64, one function per term.
//! Mirrors `glsl/common/drbokeh.glsl` (terms) and `glsl/common/aperture.glsl` (gauge, kernel
//! sample) line for line; the shaders evaluate the same expressions in f32.
//!
//! Units: `r` is a CoC radius in pixels (>= 0), `s` a signed CoC radius in pixels (positive =
//! nearer than focus), `g` the aperture gauge of an offset in pixels (Euclidean for a disk),
//! `rel` a relative disparity `d - d_f` in the stack's disparity units.
use super::{COMPAT_TAIL_PX, KERNEL_FADE_END_PX, KERNEL_FADE_START_PX};

/// GLSL `smoothstep(e0, e1, x)`: C1 Hermite ramp, exactly 0 below `e0` and 1 above `e1`.
#[inline]
pub fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

// ---------------------------------------------------------------- default model (DrBokeh)

/// Soft coverage of a pixel at gauge distance `g` by a CoC of radius `r`: a 1-px Hermite ramp
/// centred on the rim (the anti-aliased disk). Exactly 0 for `g >= r + 1/2`, so a source with
/// `r = 0` reaches only its own pixel (where it is 1/2; the area normalisation divides it out).
#[inline]
pub fn scatter(r: f64, g: f64) -> f64 {
    smoothstep(0.0, 1.0, r + 0.5 - g)
}

/// Farthest gauge distance at which [`scatter`] is non-zero.
#[inline]
pub fn support(r: f64) -> f64 {
    r + 0.5
}

/// In-layer occlusion O(y, x) in CoC pixels. `x` blocks `y` when `x` is (almost) in focus,
/// present (alpha), and `y` lies behind it:
/// - focus: 1 for `r_x <= 1/2` (every ray reaching x crosses x's depth inside x's own pixel),
///   fading to 0 at `r_x = 3/2`;
/// - behind: 1 once `y`'s signed CoC is half a pixel farther than `x`'s, 0 at equal depth.
///   A farther `y` that reaches an exactly focused `x` has `s_y < -1/2`, so it is fully
///   blocked: this is what makes in-focus pixels exact.
#[inline]
pub fn occlusion(s_y: f64, s_x: f64, r_x: f64, alpha_x: f64, is_self: bool) -> f64 {
    if is_self {
        return 1.0;
    }
    let in_focus = 1.0 - smoothstep(0.5, 1.5, r_x);
    let behind = 1.0 - smoothstep(-0.5, 0.0, s_y - s_x);
    1.0 - alpha_x * in_focus * behind
}

/// Kernel-image weights fade in over `[KERNEL_FADE_START_PX, KERNEL_FADE_END_PX]` of CoC:
/// a kernel footprint smaller than a pixel cannot be resolved and integrates to a point.
#[inline]
pub fn kernel_blend(r: f64) -> f64 {
    smoothstep(KERNEL_FADE_START_PX, KERNEL_FADE_END_PX, r)
}

/// Area normalisation A(r) from the table of exact lattice sums (`Params::area_lut`), linear
/// between entries; beyond the table it grows like the continuous integral `pi (r^2 + 1/20)`
/// of the Hermite-rimmed disk, anchored at the last entry.
pub fn area_from_lut(lut: &[f64], step: f64, r: f64) -> f64 {
    let last = lut.len() - 1;
    let r_last = last as f64 * step;
    if r >= r_last {
        return lut[last] * (r * r + 0.05) / (r_last * r_last + 0.05);
    }
    let f = r / step;
    let i = (f.floor() as usize).min(last - 1);
    let t = f - i as f64;
    lut[i] * (1.0 - t) + lut[i + 1] * t
}

/// Existence gate of a layer's visibility: the coverage V claims is dropped where no source of
/// the layer reaches x (W = 0), so layers behind show through instead of an uncoloured hole.
/// Exactly 1 for `W >= 1e-3` (an in-focus opaque pixel alone has W = 1).
#[inline]
pub fn existence_gate(w: f64) -> f64 {
    smoothstep(0.0, 1.0e-3, w)
}

// ---------------------------------------------------------------- compat model (released code)

/// The released soft step `s / (s + exp(-(a - b) g) + 1e-6)`, s = 0.1, g = 3.
#[inline]
pub fn softstep(a: f64, b: f64) -> f64 {
    0.1 / (0.1 + (-(a - b) * 3.0).exp() + 1.0e-6)
}

/// Released scatter term with `a = |d_y| K + 1 = r + 1`, `b = |x - y|` (the gauge for polygon
/// apertures), cut where it falls below ~6e-7 of its plateau so windows are finite.
#[inline]
pub fn scatter_compat(r: f64, g: f64) -> f64 {
    if g >= support_compat(r) {
        0.0
    } else {
        softstep(r + 1.0, g)
    }
}

#[inline]
pub fn support_compat(r: f64) -> f64 {
    r + 1.0 + COMPAT_TAIL_PX
}

/// Released area reweight `1 / (|d_y| K + 1)^2`, returned as the divisor.
#[inline]
pub fn area_compat(r: f64) -> f64 {
    (r + 1.0) * (r + 1.0)
}

/// Released occlusion: 1 at x == y; else `in_focal = 1 - exp(-3 (|d_x| K)^2)`,
/// `rel = 0.5 + 0.5 tanh(10 (d_y - d_x - 0.1))`, `O = (1 - in_focal) rel + in_focal`.
/// `|d_x| K` is `r_x` in pixels; 10 and 0.1 are the released constants in disparity units,
/// applied literally to relative disparities (the tanh argument is clamped to +-15, where
/// tanh is 1 to 2e-13, because GPU tanh overflows on large arguments).
#[inline]
pub fn occlusion_compat(rel_y: f64, rel_x: f64, r_x: f64, is_self: bool) -> f64 {
    if is_self {
        return 1.0;
    }
    let in_focal = 1.0 - (-3.0 * r_x * r_x).exp();
    let rel = 0.5 + 0.5 * (10.0 * (rel_y - rel_x - 0.1)).clamp(-15.0, 15.0).tanh();
    (1.0 - in_focal) * rel + in_focal
}

/// Released half-width of the square visibility box, `int((|d_x| K + 1) / 2)` (the released
/// cap by the fixed lens size R never binds here: the box always fits the tile window).
#[inline]
pub fn visibility_box_compat(r_x: f64) -> i64 {
    ((r_x + 1.0) * 0.5).floor() as i64
}

// ---------------------------------------------------------------- aperture (aperture.glsl)

/// Mirrors `Aperture::to_aperture_coords`: sources nearer than focus project it mirrored.
#[inline]
pub fn to_aperture_coords(dx: f64, dy: f64, rel: f64) -> (f64, f64) {
    if rel > 0.0 {
        (-dx, -dy)
    } else {
        (dx, dy)
    }
}

/// Mirrors `Aperture::gauge` from the GPU form `[blades (0 = disk), rotation, roundness, kernel]`.
pub fn gauge(aperture: &[f64; 4], u: f64, v: f64) -> f64 {
    let length = (u * u + v * v).sqrt();
    if aperture[0] < 3.0 || length == 0.0 {
        return length;
    }
    let n = aperture[0];
    let sector = 2.0 * std::f64::consts::PI / n;
    let theta = v.atan2(u) - aperture[1];
    let folded = theta - sector * (theta / sector).round();
    let poly = length * folded.cos() / (std::f64::consts::PI / n).cos();
    poly + (length - poly) * aperture[2]
}

/// Mirrors `KernelImage::sample`: bilinear at `(u, v)` in `[-1, 1]^2`, zero outside.
pub fn kernel_sample(weights: &[f64], size: usize, u: f64, v: f64) -> f64 {
    let n = size as f64;
    let fx = (u * 0.5 + 0.5) * n - 0.5;
    let fy = (v * 0.5 + 0.5) * n - 0.5;
    if !(fx > -1.0 && fy > -1.0 && fx < n && fy < n) {
        return 0.0;
    }
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let at = |x: f64, y: f64| -> f64 {
        if x < 0.0 || y < 0.0 || x >= n || y >= n {
            0.0
        } else {
            weights[y as usize * size + x as usize]
        }
    };
    let top = at(x0, y0) * (1.0 - tx) + at(x0 + 1.0, y0) * tx;
    let bottom = at(x0, y0 + 1.0) * (1.0 - tx) + at(x0 + 1.0, y0 + 1.0) * tx;
    top * (1.0 - ty) + bottom * ty
}
