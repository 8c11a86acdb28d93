//! Coverage shapes for cut-outs, in texture units. Coverage is binary at a point; the ray
//! tracer's pixel and lens sampling turns hard edges into fractional coverage.
use super::strokes::Strokes;

#[derive(Debug)]
pub enum Shape {
    /// Axis-aligned ellipse: centre and radii.
    Ellipse { center: [f32; 2], radii: [f32; 2] },
    /// Axis-aligned rectangle from `min` to `max`.
    Rect { min: [f32; 2], max: [f32; 2] },
    /// Thick line segments: branches, fence bars, glyph strokes, hair.
    Strokes(Strokes),
    Union(Vec<Shape>),
}

impl Shape {
    pub fn covers(&self, u: f32, v: f32) -> bool {
        match self {
            Shape::Ellipse { center, radii } => {
                let (du, dv) = ((u - center[0]) / radii[0], (v - center[1]) / radii[1]);
                du * du + dv * dv <= 1.0
            }
            Shape::Rect { min, max } => u >= min[0] && u <= max[0] && v >= min[1] && v <= max[1],
            Shape::Strokes(strokes) => strokes.covers(u, v),
            Shape::Union(shapes) => shapes.iter().any(|s| s.covers(u, v)),
        }
    }
}
