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

/// Where [`coverage_radius`]'s lift is `LIFT_AT_ZERO - LIFT_SLOPE r`, before it is rounded
/// into 0 over `+-LIFT_SOFTNESS` (a C1 join, so the backward's derivative has no jump).
const LIFT_AT_ZERO: f64 = 0.5;
const LIFT_SLOPE: f64 = 0.77;
const LIFT_SOFTNESS: f64 = 0.03;

/// The lift `coverage_radius(r) - r` as a function of `u = LIFT_AT_ZERO - LIFT_SLOPE r`, and
/// its derivative in `u`: `u` itself above the softness, 0 below it, a parabola between.
#[inline]
fn lift(u: f64) -> (f64, f64) {
    if u >= LIFT_SOFTNESS {
        (u, 1.0)
    } else if u <= -LIFT_SOFTNESS {
        (0.0, 0.0)
    } else {
        let v = u + LIFT_SOFTNESS;
        (v * v / (4.0 * LIFT_SOFTNESS), v / (2.0 * LIFT_SOFTNESS))
    }
}

/// A dip of [`coverage_radius`] below `r`: `height` times a Hermite rise over
/// `[rise_from, rise_from + rise_width]` times a Hermite fall over `[fall_from, fall_from +
/// fall_width]` (so C1, and exactly 0 outside `[rise_from, fall_from + fall_width]`).
struct Dip {
    rise_from: f64,
    rise_width: f64,
    fall_from: f64,
    fall_width: f64,
    height: f64,
}

/// The two dips where the Hermite rim at `r` blurs more than the lens: up to 40% too much
/// variance over 0.7-1.6 px and up to 12% over 1.8-2.6 px (the rim crossing the lattice's
/// first rings). Fitted to the lattice variance `r^2 / 4` (least squares of the relative error
/// over 0.55-2.75 px; the curve that matches it exactly wobbles with the rings, between
/// `r - 0.2` and `r + 0.02`). Past 2.65 px, within 4% of the lens, the rim is left at `r`.
const DIPS: [Dip; 2] = [
    Dip { rise_from: 0.605, rise_width: 0.415, fall_from: 1.393, fall_width: 0.245, height: 0.181 },
    Dip { rise_from: 1.778, rise_width: 0.477, fall_from: 2.331, fall_width: 0.317, height: 0.121 },
];

/// Where the last dip ends (2.648 px): [`coverage_radius`] is `r` itself from here on.
pub const COVERAGE_EXACT_FROM_PX: f64 = DIPS[DIPS.len() - 1].fall_from + DIPS[DIPS.len() - 1].fall_width;

/// The Hermite ramp `smoothstep(0, 1, (x - from) / width)` and its derivative in `x`.
#[inline]
fn ramp(from: f64, width: f64, x: f64) -> (f64, f64) {
    let t = ((x - from) / width).clamp(0.0, 1.0);
    (t * t * (3.0 - 2.0 * t), 6.0 * t * (1.0 - t) / width)
}

/// The sum of the [`DIPS`] at `r`, and its derivative.
#[inline]
fn dips(r: f64) -> (f64, f64) {
    DIPS.iter().fold((0.0, 0.0), |(sum, slope), dip| {
        let (rise, d_rise) = ramp(dip.rise_from, dip.rise_width, r);
        let (fall, d_fall) = ramp(dip.fall_from, dip.fall_width, r);
        (sum + dip.height * rise * (1.0 - fall), slope + dip.height * (d_rise * (1.0 - fall) - rise * d_fall))
    })
}

/// The radius whose Hermite-rimmed disk a source of CoC radius `r` scatters, chosen so that
/// the disk's lattice weights blur as much as the lens does: larger than `r` under 0.7 px,
/// smaller over 0.7-2.65 px, `r` itself from 2.65 px on.
///
/// Why: a thin lens spreads a point over a disk of radius `r`, whose variance along each axis
/// is `r^2 / 4`. The 1-px Hermite rim of radius `r` reaches no neighbour at all below
/// `r = 1/2` and gives `r = 0.6` about half the variance it should (neighbour weight 0.028 of
/// its own pixel's), so a background blurred 0.5-0.65 px behind an in-focus fence came out
/// as sharp as the pinhole input, below the plain gather (the Cycles dev split's dev-96; the
/// test split's in-focus fences, issue 46). Lifted to `r + 0.5 - 0.77 r`, the lattice
/// variance follows `r^2 / 4` within 0.005 px^2 up to 0.6 px (the exact solution is 0.5,
/// 0.542, 0.588, 0.642 at r = 0, 0.2, 0.4, 0.6). Over 0.7-2.65 px the rim at `r` blurs up to
/// 40% too much (0.351 against 0.250 px^2 at 1 px): every small light disc came out wide.
/// Two dips (`DIPS`) take that back, within 4% of the lens's variance from 0.7 px on. At `r = 0`
/// the radius is 1/2, which still reaches only the source's own pixel, so an in-focus pixel
/// stays exact. Increasing (slope >= 0.19), so bounds taken at the smallest or the largest
/// radius hold; but below `r` over the dips, so a pixel's reach is [`support`], the larger of
/// this disk's and its own footprint's.
#[inline]
pub fn coverage_radius(r: f64) -> f64 {
    r + lift(LIFT_AT_ZERO - LIFT_SLOPE * r).0 - dips(r).0
}

/// d/dr of [`coverage_radius`].
#[inline]
pub fn d_coverage_radius(r: f64) -> f64 {
    1.0 - LIFT_SLOPE * lift(LIFT_AT_ZERO - LIFT_SLOPE * r).1 - dips(r).1
}

/// Soft coverage of a pixel at gauge distance `g` by a source of CoC radius `r`: a 1-px Hermite
/// ramp centred on the rim of the disk of [`coverage_radius`] (the anti-aliased disk). Exactly
/// 0 for `g >= support(r)`, so a source with `r = 0` reaches only its own pixel.
#[inline]
pub fn scatter(r: f64, g: f64) -> f64 {
    smoothstep(0.0, 1.0, coverage_radius(r) + 0.5 - g)
}

/// Footprint of receiver `x` (CoC radius `r`) in its visibility V: which sources' alphas it
/// sees, at gauge distance `g`. The Hermite ramp at the receiver's own radius, not lifted like
/// [`scatter`]: its flat start keeps what an in-focus pixel sees its own (a wider footprint
/// there cost leaves 0.65 px in front of panels in focus 0.9 dB on dev-21 of the Cycles dev
/// split).
#[inline]
pub fn footprint(r: f64, g: f64) -> f64 {
    smoothstep(0.0, 1.0, r + 0.5 - g)
}

/// Farthest gauge distance at which a pixel of CoC radius `r` weighs anything: as a source
/// ([`scatter`], its coverage radius) or as a receiver ([`footprint`], its own radius).
#[inline]
pub fn support(r: f64) -> f64 {
    coverage_radius(r).max(r) + 0.5
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

/// The ring aperture's weight at gauge `g` through a CoC of radius `r` (mirrors
/// `crate::camera::ring_weight`): the obstruction of radius `inner r` with a one-pixel
/// Hermite edge, faded in like kernel images.
#[inline]
pub fn ring_weight(g: f64, r: f64, inner: f64) -> f64 {
    1.0 - kernel_blend(r) * (1.0 - smoothstep(0.0, 1.0, g - (inner * r - 0.5)))
}

/// Area normalisation A(r) from the table of exact lattice sums (`Params::area_lut`), a
/// Catmull-Rom spline through the entries; beyond the table it grows like the continuous
/// integral `pi (r^2 + 1/20)` of the Hermite-rimmed disk, anchored at the last entry.
///
/// Why a spline, not straight lines: A follows the coverage radius, whose slope runs from 0.35
/// to 2.1 within a quarter pixel over its dips ([`coverage_radius`]). Between straight lines
/// the slope of A then jumped by up to 30% at every entry (1/16 px), and the backward's exact
/// derivative (one segment's slope) differed from central differences across an entry by a
/// few percent. The spline's slope is continuous.
pub fn area_from_lut(lut: &[f64], step: f64, r: f64) -> f64 {
    let last = lut.len() - 1;
    let r_last = last as f64 * step;
    if r >= r_last {
        return lut[last] * (r * r + 0.05) / (r_last * r_last + 0.05);
    }
    let (p, t) = area_segment(lut, step, r);
    p[1] + 0.5 * t * (p[2] - p[0] + t * (2.0 * p[0] - 5.0 * p[1] + 4.0 * p[2] - p[3] + t * (3.0 * (p[1] - p[2]) + p[3] - p[0])))
}

/// The four entries around `r`'s segment of the area table (the ends extended in a straight
/// line) and `r`'s place in it, `t` in [0, 1).
fn area_segment(lut: &[f64], step: f64, r: f64) -> ([f64; 4], f64) {
    let last = lut.len() - 1;
    let f = r / step;
    let i = (f.floor() as usize).min(last - 1);
    let (p1, p2) = (lut[i], lut[i + 1]);
    let p0 = if i > 0 { lut[i - 1] } else { 2.0 * p1 - p2 };
    let p3 = if i + 2 <= last { lut[i + 2] } else { 2.0 * p2 - p1 };
    ([p0, p1, p2, p3], f - i as f64)
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

/// Mirrors `Aperture::gauge` from the GPU form `[shape (0 = disk, 1 = ellipse, 2 = ring,
/// >= 3 = blades, -1 = cat's-eye), rotation, roundness or squeeze or inner radius, kernel]`
/// (the cat's-eye: `[-1, a.x, a.y, 0]`, its disks centred at +-a).
pub fn gauge(aperture: &[f64; 4], u: f64, v: f64) -> f64 {
    if aperture[0] < -0.5 {
        let (ax, ay) = (aperture[1], aperture[2]);
        let k = 1.0 - (ax * ax + ay * ay);
        let q = (u * ax + v * ay).abs();
        return (q + (q * q + k * (u * u + v * v)).sqrt()) / k;
    }
    let length = (u * u + v * v).sqrt();
    if aperture[0] < 0.5 || length == 0.0 {
        return length;
    }
    if aperture[0] < 1.5 {
        let (s, c) = aperture[1].sin_cos();
        let (along, across) = (u * c + v * s, (v * c - u * s) * aperture[2]);
        return (along * along + across * across).sqrt();
    }
    if aperture[0] < 2.5 {
        return length;
    }
    let n = aperture[0];
    let sector = 2.0 * std::f64::consts::PI / n;
    let theta = v.atan2(u) - aperture[1];
    let folded = theta - sector * (theta / sector).round();
    let poly = length * folded.cos() / (std::f64::consts::PI / n).cos();
    poly + (length - poly) * aperture[2]
}

/// `KernelImage::sample` in f64: bilinear at `(u, v)` in `[-1, 1]^2`, zero outside (one body,
/// [`crate::camera::bilinear_kernel_sample`]).
pub fn kernel_sample(weights: &[f64], size: usize, u: f64, v: f64) -> f64 {
    crate::camera::bilinear_kernel_sample(weights, size, u, v)
}

// ---------------------------------------------------------------- derivatives (backward pass)
//
// `d_*` is the derivative of the forward function of the same name, exact wherever the
// forward is differentiable. At its finitely many kinks (smoothstep edges, area-table nodes,
// `|s|` at 0, the compat tail cut and tanh clamp) it returns one of the one-sided values, as
// the backward treats every piecewise choice of the forward as a constant.

/// d/dx of [`smoothstep`]`(e0, e1, x)`; 0 outside the open ramp.
#[inline]
pub fn d_smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = (x - e0) / (e1 - e0);
    if t <= 0.0 || t >= 1.0 {
        0.0
    } else {
        6.0 * t * (1.0 - t) / (e1 - e0)
    }
}

/// d/dw of [`existence_gate`].
#[inline]
pub fn d_existence_gate(w: f64) -> f64 {
    d_smoothstep(0.0, 1.0e-3, w)
}

/// d/dr of [`scatter`]`(r, g)`: the rim ramp's slope times the lift's, >= 0.
#[inline]
pub fn d_scatter(r: f64, g: f64) -> f64 {
    d_smoothstep(0.0, 1.0, coverage_radius(r) + 0.5 - g) * d_coverage_radius(r)
}

/// d/dr of [`footprint`]`(r, g)`.
#[inline]
pub fn d_footprint(r: f64, g: f64) -> f64 {
    d_smoothstep(0.0, 1.0, r + 0.5 - g)
}

/// d/dr of [`area_from_lut`]: the spline's slope (continuous at the entries), then the
/// derivative of the `r^2 + 1/20` growth.
pub fn d_area_from_lut(lut: &[f64], step: f64, r: f64) -> f64 {
    let last = lut.len() - 1;
    let r_last = last as f64 * step;
    if r >= r_last {
        return lut[last] * 2.0 * r / (r_last * r_last + 0.05);
    }
    let (p, t) = area_segment(lut, step, r);
    let d_t = 0.5 * (p[2] - p[0]) + t * (2.0 * p[0] - 5.0 * p[1] + 4.0 * p[2] - p[3]) + 1.5 * t * t * (3.0 * (p[1] - p[2]) + p[3] - p[0]);
    d_t / step
}

/// Partial derivatives of an occlusion term O(y, x). `src`/`dst` are w.r.t. the signed radii
/// `s_y`/`s_x` (default model) or the relative disparities `rel_y`/`rel_x` (compat), holding
/// `r_x` fixed; `r_x` is the separate dependence through `|s_x|`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OcclusionPartials {
    pub src: f64,
    pub dst: f64,
    pub r_x: f64,
    pub alpha_x: f64,
}

/// Partials of [`occlusion`].
pub fn d_occlusion(s_y: f64, s_x: f64, r_x: f64, alpha_x: f64, is_self: bool) -> OcclusionPartials {
    if is_self {
        return OcclusionPartials::default();
    }
    let in_focus = 1.0 - smoothstep(0.5, 1.5, r_x);
    let behind = 1.0 - smoothstep(-0.5, 0.0, s_y - s_x);
    let d_behind = -d_smoothstep(-0.5, 0.0, s_y - s_x);
    let d_in_focus = -d_smoothstep(0.5, 1.5, r_x);
    OcclusionPartials {
        src: -alpha_x * in_focus * d_behind,
        dst: alpha_x * in_focus * d_behind,
        r_x: -alpha_x * d_in_focus * behind,
        alpha_x: -in_focus * behind,
    }
}

/// d/da of [`softstep`]`(a, b)` (= -d/db), >= 0. The compat support keeps `a - b > -4`, so
/// the exponential cannot overflow.
#[inline]
pub fn d_softstep(a: f64, b: f64) -> f64 {
    let e = (-(a - b) * 3.0).exp();
    let den = 0.1 + e + 1.0e-6;
    0.3 * e / (den * den)
}

/// d/dr of [`scatter_compat`] (0 past the tail cut, where the forward is a constant 0).
#[inline]
pub fn d_scatter_compat(r: f64, g: f64) -> f64 {
    if g >= support_compat(r) {
        0.0
    } else {
        d_softstep(r + 1.0, g)
    }
}

/// d/dr of [`area_compat`].
#[inline]
pub fn d_area_compat(r: f64) -> f64 {
    2.0 * (r + 1.0)
}

/// Partials of [`occlusion_compat`] (`src`/`dst` w.r.t. `rel_y`/`rel_x`; no alpha term).
pub fn d_occlusion_compat(rel_y: f64, rel_x: f64, r_x: f64, is_self: bool) -> OcclusionPartials {
    if is_self {
        return OcclusionPartials::default();
    }
    let gauss = (-3.0 * r_x * r_x).exp();
    let in_focal = 1.0 - gauss;
    let z = 10.0 * (rel_y - rel_x - 0.1);
    let th = z.clamp(-15.0, 15.0).tanh();
    let rel = 0.5 + 0.5 * th;
    // The clamp holds tanh constant outside +-15.
    let d_rel = if z.abs() < 15.0 { 5.0 * (1.0 - th * th) } else { 0.0 };
    OcclusionPartials {
        src: (1.0 - in_focal) * d_rel,
        dst: -(1.0 - in_focal) * d_rel,
        r_x: 6.0 * r_x * gauss * (1.0 - rel),
        alpha_x: 0.0,
    }
}

/// d/dr of [`kernel_blend`].
#[inline]
pub fn d_kernel_blend(r: f64) -> f64 {
    d_smoothstep(KERNEL_FADE_START_PX, KERNEL_FADE_END_PX, r)
}

/// d/dr of [`ring_weight`] (the gauge does not depend on r).
pub fn d_ring_weight(g: f64, r: f64, inner: f64) -> f64 {
    let step = smoothstep(0.0, 1.0, g - (inner * r - 0.5));
    -d_kernel_blend(r) * (1.0 - step) + kernel_blend(r) * d_smoothstep(0.0, 1.0, g - (inner * r - 0.5)) * -inner
}

/// [`kernel_sample`] and its gradient `(value, d/du, d/dv)` (bilinear: piecewise linear
/// between texel centres, the gradient of the cell holding `(u, v)`).
pub fn kernel_sample_grad(weights: &[f64], size: usize, u: f64, v: f64) -> (f64, f64, f64) {
    let n = size as f64;
    let fx = (u * 0.5 + 0.5) * n - 0.5;
    let fy = (v * 0.5 + 0.5) * n - 0.5;
    if !(fx > -1.0 && fy > -1.0 && fx < n && fy < n) {
        return (0.0, 0.0, 0.0);
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
    let (a, b, c, d) = (at(x0, y0), at(x0 + 1.0, y0), at(x0, y0 + 1.0), at(x0 + 1.0, y0 + 1.0));
    let top = a * (1.0 - tx) + b * tx;
    let bottom = c * (1.0 - tx) + d * tx;
    let d_fx = (b - a) * (1.0 - ty) + (d - c) * ty;
    let d_fy = bottom - top;
    (top * (1.0 - ty) + bottom * ty, d_fx * 0.5 * n, d_fy * 0.5 * n)
}

/// The monotonic leaky slope: a soft step's derivative never falls below `slope` (0 = the
/// exact derivative, since soft-step derivatives are >= 0).
#[inline]
pub fn leaky(derivative: f64, slope: f64) -> f64 {
    derivative.max(slope)
}
