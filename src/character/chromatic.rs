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
        _ => Err(Error::invalid("chromatic", format!("chromatic '{spec}': expected R,G,B focus offsets in CoC pixels, e.g. 1.5,0,-1.5"))),
    }
}

/// Renders through `lens` with a per-channel focus offset (CoC pixels).
/// How many renders [`render_chromatic`] makes: one per channel, or one when no channel
/// differs (without blur, K = 0, or without offsets: one render is the exact answer).
pub fn chromatic_renders(lens: &Lens, offsets_px: [f32; 3]) -> usize {
    if lens.coc.k_px == 0.0 || offsets_px == [0.0; 3] {
        1
    } else {
        3
    }
}

pub fn render_chromatic(
    render: &dyn Fn(&LayerStack, &Lens) -> Result<Image>,
    stack: &LayerStack,
    lens: &Lens,
    offsets_px: [f32; 3],
) -> Result<Image> {
    if offsets_px.iter().any(|o| !o.is_finite()) {
        return Err(Error::invalid("chromatic", "chromatic focus offsets must be finite"));
    }
    if chromatic_renders(lens, offsets_px) == 1 {
        return render(stack, lens);
    }
    let mut shifted = Vec::with_capacity(3);
    for offset in offsets_px {
        let mut lens = lens.clone();
        lens.coc.focus_disparity += offset / lens.coc.k_px;
        // A tiny K turns a pixel of offset into an infinite focus shift: no focal plane moves
        // that far, so say which flag cannot work (before any render) instead of rendering
        // a meaningless lens.
        if !lens.coc.focus_disparity.is_finite() {
            return Err(Error::invalid("chromatic", format!(
                "chromatic focus offset of {offset} px needs an infinite focus shift at K = {:e} px per unit; \
                 use smaller chromatic offsets (--chromatic on the command line) or a larger blur",
                lens.coc.k_px
            )));
        }
        shifted.push(lens);
    }
    let channels = shifted.iter().map(|lens| render(stack, lens)).collect::<Result<Vec<_>>>()?;
    let mut out = channels[1].clone();
    for (i, p) in out.pixels.iter_mut().enumerate() {
        p[0] = channels[0].pixels[i][0];
        p[2] = channels[2].pixels[i][2];
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::stack::Layer;

    #[test]
    fn an_offset_needing_an_infinite_focus_shift_is_refused_before_rendering() {
        let layer = Layer { name: "only".into(), rgba: Image::from_fn(2, 2, |_, _| [0.5; 4]), disparity: vec![0.5; 4] };
        let stack = LayerStack::new(2, 2, vec![layer]).unwrap();
        // The smallest positive K: 1 px of offset is a focus shift of 1 / 1e-45 = inf in f32.
        let lens = Lens { coc: CocModel::new(1e-45, 0.5).unwrap(), aperture: Aperture::Disk };
        let render = |_: &LayerStack, l: &Lens| -> Result<Image> { panic!("rendered with focus {}", l.coc.focus_disparity) };
        let message = render_chromatic(&render, &stack, &lens, [0.0, 0.0, -1.0]).unwrap_err().to_string();
        assert!(message.contains("infinite focus shift") && message.contains("--chromatic"), "{message}");
    }
}
