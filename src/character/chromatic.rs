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

/// The distinct focus offsets of `offsets_px` in channel order, and for each channel the index
/// of its offset among them: channels focused alike share one render (a render gives every
/// channel of its focal plane at once), so `1,0,0` costs two renders and `0,0,0` one.
fn distinct_offsets(offsets_px: [f32; 3]) -> (Vec<f32>, [usize; 3]) {
    let mut distinct: Vec<f32> = Vec::with_capacity(3);
    let mut index = [0; 3];
    for (channel, &offset) in offsets_px.iter().enumerate() {
        index[channel] = match distinct.iter().position(|&d| d == offset) {
            Some(i) => i,
            None => {
                distinct.push(offset);
                distinct.len() - 1
            }
        };
    }
    (distinct, index)
}

/// The focal planes a render with `offsets_px` needs (focus offsets in CoC pixels) and each
/// channel's plane among them. Without blur (K = 0) every plane renders alike: one, unshifted.
fn focal_planes(lens: &Lens, offsets_px: [f32; 3]) -> (Vec<f32>, [usize; 3]) {
    if lens.coc.k_px == 0.0 {
        return (vec![0.0], [0; 3]);
    }
    distinct_offsets(offsets_px)
}

/// How many renders [`render_chromatic`] makes: one per distinct focal plane, so one when no
/// channel differs (or without blur, where one render is the exact answer).
pub fn chromatic_renders(lens: &Lens, offsets_px: [f32; 3]) -> usize {
    focal_planes(lens, offsets_px).0.len()
}

/// Renders through `lens` with a per-channel focus offset (CoC pixels): one render per
/// distinct focal plane ([`chromatic_renders`]), channel `c` taken from its plane's render.
/// Every term of a render (each tap's weight, occlusion, visibility) depends on the CoC of its
/// focal plane, so planes share no pass; channels sharing a plane share its render.
pub fn render_chromatic(
    render: &dyn Fn(&LayerStack, &Lens) -> Result<Image>,
    stack: &LayerStack,
    lens: &Lens,
    offsets_px: [f32; 3],
) -> Result<Image> {
    if offsets_px.iter().any(|o| !o.is_finite()) {
        return Err(Error::invalid("chromatic", "chromatic focus offsets must be finite"));
    }
    let (offsets, index) = focal_planes(lens, offsets_px);
    // Every plane's lens first: an impossible shift is refused before any render.
    let lenses = offsets.iter().map(|&offset| shifted_focus(lens, offset)).collect::<Result<Vec<_>>>()?;
    if let [lens] = &lenses[..] {
        return render(stack, lens);
    }
    let planes = lenses.iter().map(|lens| render(stack, lens)).collect::<Result<Vec<_>>>()?;
    // Alpha (coverage) comes from the green channel's plane.
    let mut out = planes[index[1]].clone();
    for (i, p) in out.pixels.iter_mut().enumerate() {
        p[0] = planes[index[0]].pixels[i][0];
        p[2] = planes[index[2]].pixels[i][2];
    }
    Ok(out)
}

/// `lens` with its focus moved by `offset` CoC pixels (`d_f + offset / K`; unmoved for 0).
fn shifted_focus(lens: &Lens, offset: f32) -> Result<Lens> {
    let mut lens = lens.clone();
    if offset == 0.0 {
        return Ok(lens);
    }
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
    Ok(lens)
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

    #[test]
    fn channels_focused_alike_share_one_render() {
        let layer = Layer { name: "only".into(), rgba: Image::from_fn(2, 2, |_, _| [0.5; 4]), disparity: vec![0.5; 4] };
        let stack = LayerStack::new(2, 2, vec![layer]).unwrap();
        let lens = Lens { coc: CocModel::new(4.0, 0.5).unwrap(), aperture: Aperture::Disk };
        // Each fake render writes its focus disparity into every channel and counts itself.
        let calls = std::cell::Cell::new(0);
        let render = |_: &LayerStack, l: &Lens| -> Result<Image> {
            calls.set(calls.get() + 1);
            Ok(Image::from_fn(2, 2, |_, _| [l.coc.focus_disparity; 4]))
        };
        for (offsets, renders) in [([2.0, 0.0, 0.0], 2), ([0.0, 0.0, 0.0], 1), ([1.0, 1.0, 1.0], 1), ([2.0, 0.0, -2.0], 3), ([-4.0, 0.0, -4.0], 2)] {
            calls.set(0);
            let out = render_chromatic(&render, &stack, &lens, offsets).unwrap();
            assert_eq!(calls.get(), renders, "{offsets:?}");
            assert_eq!(chromatic_renders(&lens, offsets), renders, "{offsets:?}");
            // Channel c (and alpha: green's) from the render focused at d_f + offset_c / K.
            let expected = [offsets[0], offsets[1], offsets[2], offsets[1]].map(|o| 0.5 + o / 4.0);
            assert_eq!(out.get(1, 1), expected, "{offsets:?}");
        }
    }
}
