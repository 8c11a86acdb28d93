//! Longitudinal chromatic aberration: each colour channel focuses at a slightly different
//! distance. Rendering the frame three times, render `c` with its focus moved by
//! `offset_c` CoC pixels (`d_f + offset_c / K`), and taking channel `c` from render `c` is
//! exact for a per-channel focal plane. Alpha (coverage) comes from the green render.
use crate::image::Image;
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::{Error, Result};

/// Parses the CLI form `R,G,B` (focus offsets in CoC pixels; positive = focused nearer).
pub fn parse_offsets(spec: &str) -> Result<[f32; 3]> {
    let values: Vec<f32> = spec.split(',').filter_map(|v| v.trim().parse().ok()).collect();
    match values[..] {
        [r, g, b] if values.iter().all(|v| v.is_finite()) && spec.split(',').count() == 3 => Ok([r, g, b]),
        _ => Err(Error::param(format!("chromatic '{spec}': expected R,G,B focus offsets in CoC pixels, e.g. 1.5,0,-1.5"))),
    }
}

/// Renders through `lens` with a per-channel focus offset (CoC pixels).
pub fn render_chromatic(
    render: &dyn Fn(&LayerStack, &Lens) -> Result<Image>,
    stack: &LayerStack,
    lens: &Lens,
    offsets_px: [f32; 3],
) -> Result<Image> {
    if offsets_px.iter().any(|o| !o.is_finite()) {
        return Err(Error::param("chromatic focus offsets must be finite"));
    }
    // Without blur (K = 0) or offsets no channel differs: one render is the exact answer.
    if lens.coc.k_px == 0.0 || offsets_px == [0.0; 3] {
        return render(stack, lens);
    }
    let mut channels = Vec::with_capacity(3);
    for offset in offsets_px {
        let mut shifted = lens.clone();
        shifted.coc.focus_disparity += offset / lens.coc.k_px;
        channels.push(render(stack, &shifted)?);
    }
    let mut out = channels[1].clone();
    for (i, p) in out.pixels.iter_mut().enumerate() {
        p[0] = channels[0].pixels[i][0];
        p[2] = channels[2].pixels[i][2];
    }
    Ok(out)
}
