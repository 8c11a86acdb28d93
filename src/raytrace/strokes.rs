//! Thin structures as sets of thick segments (capsules): branches, fences, glyph strokes and
//! hair. These are what single-image defocus gets wrong, so every scene has some.
use super::grid::Grid;
use super::noise::scatter;

#[derive(Clone, Copy, Debug)]
pub struct Segment {
    pub a: [f32; 2],
    pub b: [f32; 2],
    pub half_width: f32,
}

impl Segment {
    fn distance_sq(&self, p: [f32; 2]) -> f32 {
        let (ab, ap) = ([self.b[0] - self.a[0], self.b[1] - self.a[1]], [p[0] - self.a[0], p[1] - self.a[1]]);
        let len_sq = ab[0] * ab[0] + ab[1] * ab[1];
        let t = if len_sq > 0.0 { ((ap[0] * ab[0] + ap[1] * ab[1]) / len_sq).clamp(0.0, 1.0) } else { 0.0 };
        let (dx, dy) = (ap[0] - t * ab[0], ap[1] - t * ab[1]);
        dx * dx + dy * dy
    }
}

/// A set of segments with a bounding box and a uniform grid over it, so a point is tested only
/// against the segments whose padded box overlaps its cell (the branches scene has thousands
/// of ray hits per pixel and hundreds of segments; a linear scan dominated the ray tracer).
#[derive(Debug)]
pub struct Strokes {
    segments: Vec<Segment>,
    min: [f32; 2],
    max: [f32; 2],
    grid: Grid,
}

impl Strokes {
    pub fn new(segments: Vec<Segment>) -> Self {
        let (mut min, mut max) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for s in &segments {
            let (lo, hi) = s.padded_box();
            for axis in 0..2 {
                min[axis] = min[axis].min(lo[axis]);
                max[axis] = max[axis].max(hi[axis]);
            }
        }
        let boxes: Vec<_> = segments.iter().map(Segment::padded_box).collect();
        let grid = Grid::new(&boxes, min, max);
        Self { segments, min, max, grid }
    }

    /// The box `(lo, hi)` holding every covered point.
    pub fn bounds(&self) -> ([f32; 2], [f32; 2]) {
        (self.min, self.max)
    }

    pub fn covers(&self, u: f32, v: f32) -> bool {
        if u < self.min[0] || u > self.max[0] || v < self.min[1] || v > self.max[1] {
            return false;
        }
        self.grid.candidates([u, v]).iter().any(|&i| {
            let s = &self.segments[i as usize];
            let (lo, hi) = s.padded_box();
            u >= lo[0] && u <= hi[0] && v >= lo[1] && v <= hi[1] && s.distance_sq([u, v]) <= s.half_width * s.half_width
        })
    }
}

impl Segment {
    /// The segment's bounding box grown by its half width: every covered point lies inside.
    fn padded_box(&self) -> ([f32; 2], [f32; 2]) {
        let lo = [self.a[0].min(self.b[0]) - self.half_width, self.a[1].min(self.b[1]) - self.half_width];
        let hi = [self.a[0].max(self.b[0]) + self.half_width, self.a[1].max(self.b[1]) + self.half_width];
        (lo, hi)
    }
}

/// A recursively forking branch from `root` growing at `angle` (radians, 0 = +u), thinning
/// and shortening at each fork; `depth` forks deep. Twigs get thinner than a pixel.
pub fn branches(root: [f32; 2], angle: f32, length: f32, width: f32, depth: u32, seed: u32) -> Vec<Segment> {
    let mut out = Vec::new();
    grow(&mut out, root, angle, length, width, depth, seed, 1);
    out
}

#[allow(clippy::too_many_arguments)] // one recursion step of the generator above
fn grow(out: &mut Vec<Segment>, from: [f32; 2], angle: f32, length: f32, width: f32, depth: u32, seed: u32, id: u32) {
    let bend = (scatter(seed, id) - 0.5) * 0.5;
    let heading = angle + bend;
    let to = [from[0] + length * heading.cos(), from[1] + length * heading.sin()];
    out.push(Segment { a: from, b: to, half_width: width * 0.5 });
    if depth == 0 {
        return;
    }
    let spread = 0.35 + 0.4 * scatter(seed, id * 2 + 7);
    for (k, side) in [(0u32, -1.0f32), (1, 1.0)] {
        let shrink = 0.62 + 0.2 * scatter(seed, id * 3 + k);
        grow(out, to, heading + side * spread, length * shrink, width * 0.62, depth - 1, seed, id * 2 + k);
    }
}

/// A picket fence: vertical bars every `spacing` over `[u0, u1]` between `top` and `bottom`,
/// plus two horizontal rails.
pub fn fence(u0: f32, u1: f32, top: f32, bottom: f32, spacing: f32, bar_width: f32) -> Vec<Segment> {
    let mut out = Vec::new();
    let mut u = u0;
    while u <= u1 {
        out.push(Segment { a: [u, top], b: [u, bottom], half_width: bar_width * 0.5 });
        u += spacing;
    }
    for rail in [0.25, 0.75] {
        let v = top + (bottom - top) * rail;
        out.push(Segment { a: [u0, v], b: [u1, v], half_width: bar_width * 0.35 });
    }
    out
}

/// Fine strands fanning out around an ellipse (a head): thinner than a pixel at the tips.
pub fn hair(center: [f32; 2], radii: [f32; 2], count: u32, length: f32, width: f32, seed: u32) -> Vec<Segment> {
    (0..count)
        .map(|i| {
            // Strands over the upper half and the sides, angles in (-pi, 0) plus a little.
            let phi = -std::f32::consts::PI * (-0.1 + 1.2 * (i as f32 + scatter(seed, i)) / count as f32);
            let root = [center[0] + radii[0] * phi.cos() * 0.9, center[1] + radii[1] * phi.sin() * 0.9];
            let reach = length * (0.5 + scatter(seed, i + 999));
            let tilt = phi + (scatter(seed, i + 77) - 0.5) * 0.6;
            Segment { a: root, b: [root[0] + reach * tilt.cos(), root[1] + reach * tilt.sin()], half_width: width * 0.5 }
        })
        .collect()
}

/// Block capitals drawn as strokes on a 4 x 6 grid per glyph (only the letters used by the
/// scenes). `origin` is the top-left corner, `height` the cap height.
pub fn text(message: &str, origin: [f32; 2], height: f32, stroke: f32) -> Vec<Segment> {
    let cell = height / 6.0;
    let mut out = Vec::new();
    for (i, ch) in message.chars().enumerate() {
        let x0 = origin[0] + i as f32 * cell * 5.0;
        for &[(ax, ay), (bx, by)] in glyph(ch) {
            let a = [x0 + ax as f32 * cell, origin[1] + ay as f32 * cell];
            let b = [x0 + bx as f32 * cell, origin[1] + by as f32 * cell];
            out.push(Segment { a, b, half_width: stroke * 0.5 });
        }
    }
    out
}

type Stroke = [(u8, u8); 2];

fn glyph(ch: char) -> &'static [Stroke] {
    match ch.to_ascii_uppercase() {
        'L' => &[[(0, 0), (0, 6)], [(0, 6), (4, 6)]],
        'E' => &[[(0, 0), (0, 6)], [(0, 0), (4, 0)], [(0, 3), (3, 3)], [(0, 6), (4, 6)]],
        'N' => &[[(0, 6), (0, 0)], [(0, 0), (4, 6)], [(4, 6), (4, 0)]],
        'S' => &[[(4, 0), (0, 0)], [(0, 0), (0, 3)], [(0, 3), (4, 3)], [(4, 3), (4, 6)], [(4, 6), (0, 6)]],
        'B' => &[[(0, 0), (0, 6)], [(0, 0), (3, 0)], [(3, 0), (4, 1)], [(4, 1), (4, 2)], [(4, 2), (3, 3)], [(0, 3), (3, 3)], [(3, 3), (4, 4)], [(4, 4), (4, 5)], [(4, 5), (3, 6)], [(3, 6), (0, 6)]],
        'U' => &[[(0, 0), (0, 6)], [(0, 6), (4, 6)], [(4, 6), (4, 0)]],
        'R' => &[[(0, 6), (0, 0)], [(0, 0), (4, 0)], [(4, 0), (4, 3)], [(4, 3), (0, 3)], [(1, 3), (4, 6)]],
        'O' => &[[(0, 0), (4, 0)], [(4, 0), (4, 6)], [(4, 6), (0, 6)], [(0, 6), (0, 0)]],
        'K' => &[[(0, 0), (0, 6)], [(4, 0), (0, 3)], [(0, 3), (4, 6)]],
        'H' => &[[(0, 0), (0, 6)], [(4, 0), (4, 6)], [(0, 3), (4, 3)]],
        'F' => &[[(0, 0), (0, 6)], [(0, 0), (4, 0)], [(0, 3), (3, 3)]],
        'T' => &[[(0, 0), (4, 0)], [(2, 0), (2, 6)]],
        'A' => &[[(0, 6), (0, 0)], [(0, 0), (4, 0)], [(4, 0), (4, 6)], [(0, 3), (4, 3)]],
        'D' => &[[(0, 0), (0, 6)], [(0, 0), (3, 0)], [(3, 0), (4, 1)], [(4, 1), (4, 5)], [(4, 5), (3, 6)], [(3, 6), (0, 6)]],
        'P' => &[[(0, 6), (0, 0)], [(0, 0), (4, 0)], [(4, 0), (4, 3)], [(4, 3), (0, 3)]],
        'I' => &[[(2, 0), (2, 6)], [(1, 0), (3, 0)], [(1, 6), (3, 6)]],
        _ => &[],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strokes_cover_their_centre_lines_and_nothing_far_away() {
        let s = Strokes::new(fence(-1.0, 1.0, -0.5, 0.5, 0.25, 0.02));
        assert!(s.covers(0.0, 0.1), "a bar at u = 0");
        assert!(s.covers(0.125, 0.25), "the lower rail at v = 0.25");
        assert!(!s.covers(0.125, 0.1), "gap between bars, between rails");
        assert!(!s.covers(0.0, 0.6), "below the fence");
    }

    #[test]
    fn grid_lookup_agrees_with_a_linear_scan() {
        let segments = branches([0.0, 1.0], -1.5, 0.4, 0.05, 7, 3);
        let s = Strokes::new(segments.clone());
        let scan = |u: f32, v: f32| segments.iter().any(|g| g.distance_sq([u, v]) <= g.half_width * g.half_width);
        let mut covered = 0;
        for j in 0..400 {
            for i in 0..400 {
                let (u, v) = (-1.2 + 2.4 * i as f32 / 399.0, -0.6 + 1.8 * j as f32 / 399.0);
                assert_eq!(s.covers(u, v), scan(u, v), "({u}, {v})");
                covered += usize::from(scan(u, v));
            }
        }
        assert!(covered > 1000, "the grid of points must hit the branches ({covered})");
    }

    #[test]
    fn branch_twigs_get_thinner_than_their_trunk() {
        let segs = branches([0.0, 1.0], -1.5, 0.4, 0.05, 5, 3);
        assert_eq!(segs.len(), (1 << 6) - 1, "a full binary tree of depth 5");
        let thinnest = segs.iter().map(|s| s.half_width).fold(f32::INFINITY, f32::min);
        assert!(thinnest < 0.05 * 0.5 * 0.1);
    }
}
