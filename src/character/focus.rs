//! Focus by picking a pixel: the disparity the user clicked on.
use crate::stack::LayerStack;
use crate::{Error, Result};

/// Coverage from which a layer counts as what the user sees at a pixel (as `flatten` uses).
const COVERING_ALPHA: f32 = 0.5;

/// Disparity of the front-most layer covering pixel `(x, y)` of the frame with alpha >= 0.5,
/// else the flattened stack's disparity there (a pixel only partly covered by every layer).
/// The frame lies `frame_margin` pixels inside the stack's edge (a canvas extended beyond it:
/// [`crate::input::LoadedInput::frame_margin`]).
pub fn focus_disparity_at(stack: &LayerStack, x: usize, y: usize, frame_margin: usize) -> Result<f32> {
    let (width, height) = (stack.width - 2 * frame_margin, stack.height - 2 * frame_margin);
    if x >= width || y >= height {
        return Err(Error::invalid("focus pixel", format!("focus pixel ({x}, {y}) is outside the {width}x{height} image")));
    }
    let i = (y + frame_margin) * stack.width + x + frame_margin;
    let covering = stack.layers.iter().find(|l| l.rgba.pixels[i][3] >= COVERING_ALPHA);
    match covering {
        Some(layer) => Ok(layer.disparity[i]),
        None => Ok(stack.flatten().1[i]),
    }
}

/// Parses the CLI form `X,Y` (pixels, origin top-left).
pub fn parse_pixel(spec: &str) -> Result<[usize; 2]> {
    let parsed = spec.split_once(',').and_then(|(x, y)| Some([x.trim().parse().ok()?, y.trim().parse().ok()?]));
    parsed.ok_or_else(|| Error::invalid("focus pixel", format!("focus pixel '{spec}': expected X,Y in pixels, e.g. 640,360")))
}
