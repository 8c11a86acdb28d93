//! The cat's-eye of a convex gauge aperture (a straight-bladed polygon or the anamorphic
//! ellipse) as one shape per 16 px tile: the base `B` clipped by the vignetting unit disk
//! `D(s)` centred at the tile's shift `s` ([`crate::character::CatsEye::shift`]), recentred on
//! the centroid `c` of `B ∩ D(s)` as [`crate::character::kernels::cats_eye`] recentres its
//! kernel image, and cut to the unit disk (the renderers' support, which that kernel image is
//! cut to as well):
//!
//! `K = ((B ∩ D(s)) - c) ∩ D(0)`.
//!
//! K is convex and contains the origin, and the gauge of an intersection of convex sets that
//! contain 0 is the largest of their gauges ([`Eye::gauge`]), each in closed form. The centroid
//! has none: [`clipped_centroid`] integrates the closed-form rows of `B ∩ D(s)` in f64, once per
//! tile on the host; renderers read it from a table.
use super::aperture::Aperture;

/// Rows integrated by [`clipped_centroid`] (cosine-spaced, so the square-root ends of the
/// rows' widths cost nothing; the kinks where a blade meets the disk err by ~(pi / n)^2).
const CENTROID_ROWS: usize = 512;

/// The centroid of `B ∩ D(shift)` and its area (unit-radius units), or `None` when the two do
/// not overlap. `base` is a polygon (roundness 0) or an ellipse ([`vignettes_in_one_pass`]).
pub fn clipped_centroid(base: &Aperture, shift: [f64; 2]) -> Option<ClippedShape> {
    let base_rows = BaseRows::new(base);
    let row = |v: f64| -> Option<(f64, f64)> {
        let (lo, hi) = base_rows.row(v)?;
        let room = 1.0 - (v - shift[1]) * (v - shift[1]);
        if room < 0.0 {
            return None;
        }
        let half = room.sqrt();
        let (lo, hi) = (lo.max(shift[0] - half), hi.min(shift[0] + half));
        (lo < hi).then_some((lo, hi))
    };
    // The heights where the intersection has a row: an interval (both are convex), found by a
    // coarse scan and bisected to 1e-12 at both ends.
    let (v_lo, v_hi) = ((shift[1] - 1.0).max(-1.0), (shift[1] + 1.0).min(1.0));
    let coarse = 256;
    let at = |i: usize| v_lo + (v_hi - v_lo) * i as f64 / coarse as f64;
    let first = (0..=coarse).find(|&i| row(at(i)).is_some())?;
    let last = (0..=coarse).rev().find(|&i| row(at(i)).is_some())?;
    let edge = |mut inside: f64, mut outside: f64| {
        for _ in 0..60 {
            let mid = 0.5 * (inside + outside);
            if row(mid).is_some() {
                inside = mid
            } else {
                outside = mid
            }
        }
        inside
    };
    let bottom = if first == 0 { v_lo } else { edge(at(first), at(first - 1)) };
    let top = if last == coarse { v_hi } else { edge(at(last), at(last + 1)) };
    // v = mid - half cos(t): dv = half sin(t) dt vanishes where the widths go like sqrt.
    let (mid, half) = (0.5 * (bottom + top), 0.5 * (top - bottom));
    let (mut area, mut moment_u, mut moment_v) = (0.0f64, 0.0f64, 0.0f64);
    for i in 0..CENTROID_ROWS {
        let t = (i as f64 + 0.5) / CENTROID_ROWS as f64 * std::f64::consts::PI;
        let v = mid - half * t.cos();
        let Some((lo, hi)) = row(v) else { continue };
        let weight = half * t.sin() * std::f64::consts::PI / CENTROID_ROWS as f64;
        let width = hi - lo;
        area += width * weight;
        moment_u += width * 0.5 * (lo + hi) * weight;
        moment_v += width * v * weight;
    }
    (area > 0.0).then(|| ClippedShape { area, centroid: [moment_u / area, moment_v / area] })
}

/// Area and centroid of `B ∩ D(s)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClippedShape {
    pub area: f64,
    pub centroid: [f64; 2],
}

/// Whether [`Aperture::Vignetted`] renders the cat's-eye of `base` per tile in one pass (the
/// disk in closed form, straight-bladed polygons and the ellipse through [`Eye`]). Rounded
/// blades, rings and kernel images are not a max of closed-form gauges: they keep the node grid.
pub fn vignettes_in_one_pass(base: &Aperture) -> bool {
    match *base {
        Aperture::Disk | Aperture::Ellipse { .. } => true,
        Aperture::Polygon { roundness, .. } => roundness == 0.0,
        _ => false,
    }
}

/// The most blades a polygon has ([`Aperture::polygon`]).
const MAX_BLADES: usize = 16;

/// A polygon's edge normals over cos(pi / n) (its half-planes `n_i . p <= 1`), from its GPU form
/// `[blades, rotation, ..]`.
fn polygon_normals(base: &[f64; 4]) -> ([[f64; 2]; MAX_BLADES], usize) {
    let blades = base[0] as usize;
    let apothem = (std::f64::consts::PI / base[0]).cos();
    let mut normals = [[0.0; 2]; MAX_BLADES];
    for (i, normal) in normals.iter_mut().enumerate().take(blades) {
        let (ny, nx) = (base[1] + std::f64::consts::TAU * i as f64 / base[0]).sin_cos();
        *normal = [nx / apothem, ny / apothem];
    }
    (normals, blades)
}

/// An ellipse's long axis and its short axis times the squeeze, from its GPU form `[1,
/// rotation, squeeze, ..]`: its gauge is `|(p . a, p . b)|`.
fn ellipse_axes(base: &[f64; 4]) -> [[f64; 2]; 2] {
    let (s, c) = base[1].sin_cos();
    [[c, s], [-s * base[2], c * base[2]]]
}

/// The rows of the unit base aperture in closed form (f64). Fixed arrays: nothing allocated
/// per tile.
#[allow(clippy::large_enum_variant)]
enum BaseRows {
    Polygon([[f64; 2]; MAX_BLADES], usize),
    Ellipse([[f64; 2]; 2]),
}

impl BaseRows {
    fn new(base: &Aperture) -> Self {
        assert!(vignettes_in_one_pass(base) && *base != Aperture::Disk, "no closed-form rows for {base:?}");
        let gpu = base.gpu_params().map(|x| x as f64);
        match base {
            Aperture::Polygon { .. } => {
                let (normals, count) = polygon_normals(&gpu);
                BaseRows::Polygon(normals, count)
            }
            _ => BaseRows::Ellipse(ellipse_axes(&gpu)),
        }
    }

    /// The row `[lo, hi]` at height v, or `None` where it is empty.
    fn row(&self, v: f64) -> Option<(f64, f64)> {
        match self {
            BaseRows::Polygon(normals, count) => {
                let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
                for &[nx, ny] in &normals[..*count] {
                    let room = 1.0 - ny * v;
                    if nx.abs() < 1e-12 {
                        if room < 0.0 {
                            return None;
                        }
                    } else if nx > 0.0 {
                        hi = hi.min(room / nx);
                    } else {
                        lo = lo.max(room / nx);
                    }
                }
                (lo < hi).then_some((lo, hi))
            }
            BaseRows::Ellipse([a, b]) => {
                // (p . a)^2 + (p . b)^2 <= 1: quadratic in u.
                let qa = a[0] * a[0] + b[0] * b[0];
                let qb = (a[0] * a[1] + b[0] * b[1]) * v;
                let qc = (a[1] * a[1] + b[1] * b[1]) * v * v - 1.0;
                let disc = qb * qb - qa * qc;
                if disc <= 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                Some(((-qb - root) / qa, (-qb + root) / qa))
            }
        }
    }
}

/// One tile's K, ready for its gauge: the shift `s`, the centroid `c` of `B ∩ D(s)`, and the
/// constants of the gauges of `B - c` and `D(s) - c`.
#[derive(Clone, Debug, PartialEq)]
pub struct Eye {
    pub shift: [f64; 2],
    pub centroid: [f64; 2],
    /// The clipping disk's centre seen from c, `e = s - c`, and `1 - |e|^2`.
    clip: ([f64; 2], f64),
    base: EyeBase,
}

#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)]
enum EyeBase {
    /// `n_i / (1 - n_i . c)`: `B - c` is `n_i . q <= 1 - n_i . c`.
    Polygon([[f64; 2]; MAX_BLADES], usize),
    /// The axes, and `B - c` in `q = M p`: the unit disk centred at `-M c`, with its `1 - |M c|^2`.
    Ellipse([[f64; 2]; 2], [f64; 2], f64),
}

impl Eye {
    /// K of the base with GPU form `base` ([`Aperture::gpu_params`]: blades and rotation, or 1,
    /// rotation and squeeze) at shift `shift`, recentred on `centroid` ([`clipped_centroid`]).
    pub fn new(base: &[f64; 4], shift: [f64; 2], centroid: [f64; 2]) -> Self {
        let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
        let e = [shift[0] - centroid[0], shift[1] - centroid[1]];
        let base = if base[0] >= 3.0 {
            let (mut normals, count) = polygon_normals(base);
            for n in &mut normals[..count] {
                let scale = 1.0 / (1.0 - dot(*n, centroid));
                *n = [n[0] * scale, n[1] * scale];
            }
            EyeBase::Polygon(normals, count)
        } else {
            let axes = ellipse_axes(base);
            let mc = [dot(axes[0], centroid), dot(axes[1], centroid)];
            EyeBase::Ellipse(axes, mc, 1.0 - dot(mc, mc))
        };
        Self { shift, centroid, clip: (e, 1.0 - dot(e, e)), base }
    }

    /// Gauge of K at p: the largest of the gauges of `B - c`, of `D(s) - c` and of the unit disk
    /// (`|p|`). A unit disk centred at `e` has gauge `(-p.e + sqrt((p.e)^2 + k |p|^2)) / k`
    /// with `k = 1 - |e|^2` ([`super::cats_eye_gauge`]); `B - c` is a polygon's half-planes
    /// moved by -c, or for the ellipse `|M p| <= 1` the disk centred at `-M c` in `q = M p`.
    /// Mirrors `gauge_pair` in `glsl/common/gauge.glsl`.
    pub fn gauge(&self, u: f64, v: f64) -> f64 {
        let disk_gauge = |p: [f64; 2], e: [f64; 2], k: f64| {
            let pe = p[0] * e[0] + p[1] * e[1];
            (-pe + (pe * pe + k * (p[0] * p[0] + p[1] * p[1])).sqrt()) / k
        };
        let clip = disk_gauge([u, v], self.clip.0, self.clip.1);
        let base = match &self.base {
            EyeBase::Polygon(normals, count) => {
                normals[..*count].iter().map(|n| n[0] * u + n[1] * v).fold(f64::NEG_INFINITY, f64::max)
            }
            EyeBase::Ellipse([a, b], mc, k) => {
                let q = [a[0] * u + a[1] * v, b[0] * u + b[1] * v];
                disk_gauge(q, [-mc[0], -mc[1]], *k)
            }
        };
        clip.max(base).max(u.hypot(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bases() -> Vec<Aperture> {
        vec![
            Aperture::polygon(6, 0.0, 0.0).unwrap(),
            Aperture::polygon(5, 17.0, 0.0).unwrap(),
            Aperture::polygon(3, 40.0, 0.0).unwrap(),
            Aperture::anamorphic(1.8, 0.0).unwrap(),
            Aperture::anamorphic(2.5, 30.0).unwrap(),
        ]
    }

    fn inside_clipped(base: &Aperture, shift: [f64; 2], u: f64, v: f64) -> bool {
        base.gauge(u as f32, v as f32) <= 1.0 && (u - shift[0]).hypot(v - shift[1]) <= 1.0
    }

    /// Area and centroid against counting a 1200^2 grid over [-1, 1]^2.
    #[test]
    fn centroid_and_area_match_brute_force_sampling() {
        let n = 1200;
        for base in bases() {
            for shift in [[0.0, 0.0], [0.35, -0.2], [-0.9, 0.8], [0.0, 1.4]] {
                let got = clipped_centroid(&base, shift).unwrap();
                let (mut count, mut su, mut sv) = (0usize, 0.0f64, 0.0f64);
                for j in 0..n {
                    for i in 0..n {
                        let (u, v) = ((i as f64 + 0.5) / n as f64 * 2.0 - 1.0, (j as f64 + 0.5) / n as f64 * 2.0 - 1.0);
                        if inside_clipped(&base, shift, u, v) {
                            count += 1;
                            su += u;
                            sv += v;
                        }
                    }
                }
                let area = count as f64 * 4.0 / (n * n) as f64;
                let centroid = [su / count as f64, sv / count as f64];
                assert!((got.area - area).abs() < 2e-3 * area.max(0.1), "{base:?} {shift:?}: area {} vs {area}", got.area);
                for k in 0..2 {
                    assert!((got.centroid[k] - centroid[k]).abs() < 2e-3, "{base:?} {shift:?}: centroid {:?} vs {centroid:?}", got.centroid);
                }
            }
        }
        // The unclipped base is centred.
        let hexagon = clipped_centroid(&bases()[0], [0.0, 0.0]).unwrap();
        assert!(hexagon.centroid[0].abs() < 1e-9 && hexagon.centroid[1].abs() < 1e-9);
        assert!(clipped_centroid(&bases()[0], [2.5, 0.0]).is_none(), "no overlap");
    }

    /// The gauge's unit ball is K: inside exactly where the point-in-set test says so (away
    /// from the rim, where f32 gauges of the base decide), and the gauge is homogeneous.
    #[test]
    fn eye_gauge_is_the_gauge_of_the_recentred_clipped_base() {
        for base in bases() {
            let gpu = base.gpu_params().map(|x| x as f64);
            for shift in [[0.35, -0.2], [-0.9, 0.8], [0.0, 1.4], [1.2, 0.3]] {
                let c = clipped_centroid(&base, shift).unwrap().centroid;
                let eye = Eye::new(&gpu, shift, c);
                let (mut inside, mut total) = (0, 0);
                for j in 0..80 {
                    for i in 0..80 {
                        let (u, v) = (i as f64 / 40.0 - 1.0 + 0.0123, j as f64 / 40.0 - 1.0 + 0.0071);
                        let g = eye.gauge(u, v);
                        let member = inside_clipped(&base, shift, u + c[0], v + c[1]) && u.hypot(v) <= 1.0;
                        total += 1;
                        if (g - 1.0).abs() > 1e-4 {
                            assert_eq!(g < 1.0, member, "{base:?} {shift:?} at ({u}, {v}): gauge {g}");
                            inside += member as usize;
                        }
                        assert!((eye.gauge(2.5 * u, 2.5 * v) - 2.5 * g).abs() < 1e-9 * g.max(1.0));
                    }
                }
                assert!(inside > 0 && inside < total, "{base:?} {shift:?}: not vacuous");
            }
        }
    }
}
