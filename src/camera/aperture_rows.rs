//! Row extents of a gauge aperture (disk, polygon, ellipse): the table that lets a gather sum
//! whole row spans instead of evaluating the aperture at every tap.
//!
//! A gather at centre x visits sources y = x + (o, oy). A source nearer than focus sees the
//! aperture through the gauge `G(o, oy)`, a farther one through `G(-o, -oy)` (the mirrored
//! aperture, [`Aperture::to_aperture_coords`]). Two sets of offsets matter at a level `c`:
//! - the interior `c * (P ∩ -P)` (P = the unit ball of G): both orientations have gauge <= c,
//!   so a source of radius r >= c + 1/2 covers the offset fully whichever side of focus it is;
//! - the hull of `c * (P ∪ -P)`: outside it both gauges are >= c, so a source whose support is
//!   below c adds an exact zero there.
//!
//! P is convex, so each row of either set is one interval. The table samples the rows of the
//! unit sets at heights v in [-1, 1] (every gauge is at least the Euclidean length, so P lies
//! in the unit disk), and each entry is *conservative over its neighbours*: the interior entry
//! of a segment is inside the interior's row at every height of the segment and the two next
//! to it, the outer entry contains the hull's row there. A shader that looks up the segment of
//! `oy / c` (f32 rounding moves it by far less than a segment) and scales by c gets an interval
//! it may trust without evaluating the gauge; it keeps a relative margin for the gauge's own
//! f32 rounding (`glsl/common/aperture_rows.glsl`).
use super::aperture::Aperture;

/// Segments over v in [-1, 1]. At a 40 px CoC one segment spans 0.04 rows, so an entry that
/// is conservative over three segments gives up a small fraction of a pixel at the tips.
pub const APERTURE_ROW_SEGMENTS: usize = 2048;

/// Inward slack of interior entries and outward slack of outer entries (unit-radius units):
/// covers the bisection's tolerance and the boundary sampling of the outer rows (points
/// 2 pi / (64 * 2048) ~ 5e-5 apart).
const SLACK: f64 = 3e-4;

/// An empty row: `lo > hi` for both intervals.
pub const EMPTY_APERTURE_ROW: [f32; 4] = [1.0, -1.0, 1.0, -1.0];

/// Two entries per segment `i` of v in [-1, 1], each `[interior lo, interior hi, outer lo,
/// outer hi]` at unit level in offsets `o` (source column minus centre column) of a row at
/// height `v = oy / c`, `lo > hi` where the row is empty:
/// - `2i`: both orientations, the interior of `P ∩ -P` and the hull of `P ∪ -P` (a window with
///   sources on both sides of focus);
/// - `2i + 1`: `P` alone (every source nearer than focus; a window of farther ones reads the
///   entry of `-v`, negated and swapped).
///
/// `None` for shapes that are not a gauge's unit ball (kernel images, the ring).
pub fn aperture_row_table(aperture: &Aperture) -> Option<Vec<[f32; 4]>> {
    if !aperture.is_gauge_shape() {
        return None;
    }
    let n = APERTURE_ROW_SEGMENTS;
    let gauge = |o: f64, v: f64| aperture.gauge(o as f32, v as f32) as f64;
    let gauge_both = |o: f64, v: f64| gauge(o, v).max(gauge(-o, -v));
    let node_v = |j: usize| -1.0 + 2.0 * j as f64 / n as f64;
    // The interiors' rows at each node height (exact up to the bisection's tolerance).
    let interior_both: Vec<Option<(f64, f64)>> = (0..=n).map(|j| unit_row(&gauge_both, node_v(j))).collect();
    let interior_own: Vec<Option<(f64, f64)>> = (0..=n).map(|j| unit_row(&gauge, node_v(j))).collect();
    // The extreme columns near each node height, from dense boundary points of P and -P.
    let mut outer_both = vec![(f64::INFINITY, f64::NEG_INFINITY); n];
    let mut outer_own = outer_both.clone();
    let boundary_points = 64 * n;
    for k in 0..boundary_points {
        let angle = (k as f64 + 0.5) / boundary_points as f64 * std::f64::consts::TAU;
        let (dir_v, dir_o) = angle.sin_cos();
        let g = gauge(dir_o, dir_v);
        if g <= 0.0 || !g.is_finite() {
            continue;
        }
        let (o, v) = (dir_o / g, dir_v / g);
        for (o, v, own) in [(o, v, true), (-o, -v, false)] {
            // Segments whose neighbourhood [v_{i-1}, v_{i+2}] holds v: i in (f - 2, f + 1].
            let f = (v + 1.0) * 0.5 * n as f64;
            let first = ((f - 2.0).floor() as i64 + 1).max(0);
            let last = (f.floor() as i64 + 1).min(n as i64 - 1);
            for i in first..=last {
                let both = &mut outer_both[i as usize];
                *both = (both.0.min(o), both.1.max(o));
                if own {
                    let entry = &mut outer_own[i as usize];
                    *entry = (entry.0.min(o), entry.1.max(o));
                }
            }
        }
    }
    let entry = |interior: &[Option<(f64, f64)>], outer: (f64, f64), i: usize| {
        // Concave upper and convex lower ends: the tightest row over the neighbourhood is at
        // one of its two end heights.
        let ends = [i.saturating_sub(1), (i + 2).min(n)];
        let inner = match (interior[ends[0]], interior[ends[1]]) {
            (Some(a), Some(b)) => Some((a.0.max(b.0) + SLACK, a.1.min(b.1) - SLACK)),
            _ => None,
        };
        let (outer_lo, outer_hi) = (outer.0 - SLACK, outer.1 + SLACK);
        match inner {
            Some((lo, hi)) if lo <= hi => [lo as f32, hi as f32, outer_lo as f32, outer_hi as f32],
            _ if outer_lo <= outer_hi => [EMPTY_APERTURE_ROW[0], EMPTY_APERTURE_ROW[1], outer_lo as f32, outer_hi as f32],
            _ => EMPTY_APERTURE_ROW,
        }
    };
    let table = (0..n)
        .flat_map(|i| [entry(&interior_both, outer_both[i], i), entry(&interior_own, outer_own[i], i)])
        .collect();
    Some(table)
}

/// The constants of the gauge's closed form, computed here in f64 so that a shader needs no
/// trigonometry of its own (Vulkan lets cos and sin err by 2^-11): a polygon's first edge normal
/// over cos(pi / n) and the (cos, sin) of its sector angle (the gauge is max_i p . n_i over the
/// normals stepped by that rotation, blended toward |p| by roundness); an ellipse's long axis
/// and its short axis times the squeeze (the gauge is |(p . a, p . b)|); a cat's-eye's disk
/// centre a, 1 / k and k = 1 - |a|^2 ([`super::cats_eye_gauge`]). `None` for the disk, the
/// ring and kernel images.
pub fn closed_form_gauge(aperture: &Aperture) -> Option<[f32; 4]> {
    match *aperture {
        Aperture::Polygon { blades, rotation, .. } => {
            let n = blades as f64;
            let apothem = (std::f64::consts::PI / n).cos();
            let (s, c) = (rotation as f64).sin_cos();
            let (ss, sc) = (std::f64::consts::TAU / n).sin_cos();
            Some([(c / apothem) as f32, (s / apothem) as f32, sc as f32, ss as f32])
        }
        Aperture::Ellipse { squeeze, rotation } => {
            let (s, c) = (rotation as f64).sin_cos();
            let q = squeeze as f64;
            Some([c as f32, s as f32, (-s * q) as f32, (c * q) as f32])
        }
        Aperture::CatsEye { shift } => {
            let (ax, ay) = (0.5 * shift[0] as f64, 0.5 * shift[1] as f64);
            let k = 1.0 - (ax * ax + ay * ay);
            Some([ax as f32, ay as f32, (1.0 / k) as f32, k as f32])
        }
        _ => None,
    }
}

/// The interval of o in [-1, 1] with `gauge(o, v) <= 1` (gauge convex in o), or `None`.
fn unit_row(gauge: &dyn Fn(f64, f64) -> f64, v: f64) -> Option<(f64, f64)> {
    // Golden-section search for the row's smallest gauge.
    let (mut a, mut b) = (-1.0f64, 1.0f64);
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..60 {
        let (m1, m2) = (b - ratio * (b - a), a + ratio * (b - a));
        if gauge(m1, v) <= gauge(m2, v) {
            b = m2;
        } else {
            a = m1;
        }
    }
    let centre = 0.5 * (a + b);
    if gauge(centre, v) > 1.0 {
        return None;
    }
    // Bisection of each side: inside at `inside`, outside (or the window's end) at `outside`.
    let edge = |outside: f64| {
        let (mut inside, mut outside) = (centre, outside);
        if gauge(outside, v) <= 1.0 {
            return outside;
        }
        for _ in 0..40 {
            let mid = 0.5 * (inside + outside);
            if gauge(mid, v) <= 1.0 {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        inside
    };
    Some((edge(-1.0), edge(1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apertures() -> Vec<Aperture> {
        vec![
            Aperture::Disk,
            Aperture::polygon(6, 0.0, 0.0).unwrap(),
            Aperture::polygon(5, 17.0, 0.0).unwrap(),
            Aperture::polygon(9, 3.0, 0.5).unwrap(),
            Aperture::polygon(3, 40.0, 0.1).unwrap(),
            Aperture::anamorphic(1.8, 0.0).unwrap(),
            Aperture::anamorphic(2.5, 30.0).unwrap(),
            Aperture::cats_eye([0.9, -0.4]).unwrap(),
            Aperture::cats_eye([0.0, 1.4]).unwrap(),
        ]
    }

    /// The gauge from the closed-form constants equals the aperture's own.
    #[test]
    fn closed_form_gauge_matches_the_aperture() {
        assert!(closed_form_gauge(&Aperture::Disk).is_none(), "the disk's rows and gauge need no constants");
        for aperture in apertures().into_iter().filter(|a| *a != Aperture::Disk) {
            let [a, b, c, d] = closed_form_gauge(&aperture).unwrap();
            let (first, second) = ((a as f64, b as f64), (c as f64, d as f64));
            for (u, v) in [(0.3f64, 0.8f64), (-0.7, 0.1), (0.05, -0.9), (-0.4, -0.4)] {
                let expected = aperture.gauge(u as f32, v as f32) as f64;
                let got = match aperture {
                    Aperture::Ellipse { .. } => (u * first.0 + v * first.1).hypot(u * second.0 + v * second.1),
                    Aperture::CatsEye { .. } => {
                        let q = (u * first.0 + v * first.1).abs();
                        (q + (q * q + second.1 * (u * u + v * v)).sqrt()) * second.0
                    }
                    Aperture::Polygon { blades, roundness, .. } => {
                        let (mut normal, mut most) = (first, f64::MIN);
                        for _ in 0..blades {
                            most = most.max(u * normal.0 + v * normal.1);
                            normal = (normal.0 * second.0 - normal.1 * second.1, normal.0 * second.1 + normal.1 * second.0);
                        }
                        most + (u.hypot(v) - most) * roundness as f64
                    }
                    _ => u.hypot(v),
                };
                assert!((got - expected).abs() < 1e-5, "{aperture:?} at ({u}, {v}): {got} vs {expected}");
            }
        }
    }

    /// Brute force at a 40 px level, every integer row: interior columns have both gauges
    /// below the level, and every column outside the outer interval has both above it.
    #[test]
    fn entries_are_conservative_on_every_row() {
        let n = APERTURE_ROW_SEGMENTS;
        for aperture in apertures() {
            let table = aperture_row_table(&aperture).unwrap();
            assert_eq!(table.len(), 2 * n);
            let c = 40.0f32;
            // The entry of segment `seg` (`own`: P alone), as the shader reads it.
            let lookup = |v: f32, own: bool| {
                let seg = ((v + 1.0) * 0.5 * n as f32).floor() as i64;
                if (0..n as i64).contains(&seg) { table[2 * seg as usize + own as usize] } else { EMPTY_APERTURE_ROW }
            };
            // Orientation: near (P), far (-P: the entry of -v, negated), both.
            for orientation in [1, -1, 0] {
                let mut interior_columns = 0usize;
                for oy in -45i32..=45 {
                    let v = oy as f32 / c;
                    let [ilo, ihi, olo, ohi] = match orientation {
                        1 => lookup(v, true),
                        -1 => {
                            let [ilo, ihi, olo, ohi] = lookup(-v, true);
                            [-ihi, -ilo, -ohi, -olo]
                        }
                        _ => lookup(v, false),
                    };
                    let (ilo, ihi) = ((c * ilo).ceil() as i32, (c * ihi).floor() as i32);
                    let (olo, ohi) = ((c * olo).floor() as i32, (c * ohi).ceil() as i32);
                    for o in -45i32..=45 {
                        let (near, far) = (aperture.gauge(o as f32, oy as f32), aperture.gauge(-o as f32, -oy as f32));
                        let (inner, outer) = match orientation {
                            1 => (near, near),
                            -1 => (far, far),
                            _ => (near.max(far), near.min(far)),
                        };
                        if o >= ilo && o <= ihi {
                            interior_columns += 1;
                            assert!(inner <= c, "{aperture:?} ({orientation}): ({o}, {oy}) interior but gauge {inner}");
                        }
                        if o < olo || o > ohi {
                            assert!(outer >= c, "{aperture:?} ({orientation}): ({o}, {oy}) outside but gauge {outer}");
                        }
                    }
                }
                // Not vacuous: one orientation's interior holds nearly the whole ball (P less the
                // margins), both orientations' at least P ∩ -P (2/3 of a triangle).
                let area = std::f32::consts::PI * c * c * aperture.relative_area();
                let share = if orientation == 0 { 0.6 } else { 0.9 };
                assert!(interior_columns as f32 > share * area, "{aperture:?} ({orientation}): {interior_columns} of ~{area}");
            }
        }
    }

    #[test]
    fn kernel_images_have_no_table() {
        let kernel = super::super::KernelImage::from_weights(8, vec![1.0; 64]).unwrap();
        assert!(aperture_row_table(&Aperture::Kernel(kernel)).is_none());
    }
}
