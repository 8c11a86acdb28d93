//! Coverage shapes for cut-outs, in texture units. Coverage is binary at a point; the ray
//! tracer's pixel and lens sampling turns hard edges into fractional coverage.
use super::grid::Grid;
use super::strokes::Strokes;

#[derive(Debug)]
pub enum Shape {
    /// Axis-aligned ellipse: centre and radii.
    Ellipse { center: [f32; 2], radii: [f32; 2] },
    /// Axis-aligned rectangle from `min` to `max`.
    Rect { min: [f32; 2], max: [f32; 2] },
    /// Thick line segments: branches, fence bars, glyph strokes, hair.
    Strokes(Strokes),
    /// Any of several shapes; build it with [`Shape::union`].
    Union(Parts),
}

/// The shapes of a union with a grid over their bounding boxes (hundreds of leaves per
/// branch scene: a linear scan per ray hit dominated the ray tracer).
#[derive(Debug)]
pub struct Parts {
    shapes: Vec<Shape>,
    bounds: ([f32; 2], [f32; 2]),
    grid: Grid,
}

impl Shape {
    pub fn union(shapes: Vec<Shape>) -> Shape {
        let boxes: Vec<_> = shapes.iter().map(Shape::bounds).collect();
        let (mut min, mut max) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for (lo, hi) in &boxes {
            for axis in 0..2 {
                (min[axis], max[axis]) = (min[axis].min(lo[axis]), max[axis].max(hi[axis]));
            }
        }
        let grid = Grid::new(&boxes, min, max);
        Shape::Union(Parts { shapes, bounds: (min, max), grid })
    }

    /// A box `(lo, hi)` containing every covered point.
    pub fn bounds(&self) -> ([f32; 2], [f32; 2]) {
        match self {
            Shape::Ellipse { center, radii } => {
                ([center[0] - radii[0], center[1] - radii[1]], [center[0] + radii[0], center[1] + radii[1]])
            }
            Shape::Rect { min, max } => (*min, *max),
            Shape::Strokes(strokes) => strokes.bounds(),
            Shape::Union(parts) => parts.bounds,
        }
    }

    pub fn covers(&self, u: f32, v: f32) -> bool {
        match self {
            Shape::Ellipse { center, radii } => {
                let (du, dv) = ((u - center[0]) / radii[0], (v - center[1]) / radii[1]);
                du * du + dv * dv <= 1.0
            }
            Shape::Rect { min, max } => u >= min[0] && u <= max[0] && v >= min[1] && v <= max[1],
            Shape::Strokes(strokes) => strokes.covers(u, v),
            Shape::Union(parts) => {
                let (lo, hi) = parts.bounds;
                if u < lo[0] || u > hi[0] || v < lo[1] || v > hi[1] {
                    return false;
                }
                parts.grid.candidates([u, v]).iter().any(|&i| parts.shapes[i as usize].covers(u, v))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn union_lookup_agrees_with_a_linear_scan() {
        let parts = || (0..60).map(|i| Shape::Ellipse { center: [(i % 8) as f32 * 0.13 - 0.5, (i / 8) as f32 * 0.11 - 0.4], radii: [0.05 + 0.001 * i as f32, 0.03] });
        let union = Shape::union(parts().chain([Shape::Rect { min: [0.3, -0.9], max: [0.35, 0.9] }]).collect());
        let scan: Vec<Shape> = parts().chain([Shape::Rect { min: [0.3, -0.9], max: [0.35, 0.9] }]).collect();
        let mut covered = 0;
        for j in 0..300 {
            for i in 0..300 {
                let (u, v) = (-0.7 + 1.4 * i as f32 / 299.0, -1.0 + 2.0 * j as f32 / 299.0);
                let expected = scan.iter().any(|s| s.covers(u, v));
                assert_eq!(union.covers(u, v), expected, "({u}, {v})");
                covered += usize::from(expected);
            }
        }
        assert!(covered > 5000, "the points must hit the parts ({covered})");
    }
}
