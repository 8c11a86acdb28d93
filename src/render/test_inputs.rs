//! Inputs the unit tests of the image methods share (gather, scatter, gausspsf).
use crate::camera::{Aperture, CocModel};
use crate::image::Image;
use crate::render::Lens;

/// A disk aperture through `k_px` pixels of CoC per unit of disparity, focused at `focus`.
pub(crate) fn disk_lens(k_px: f32, focus: f32) -> Lens {
    Lens { coc: CocModel::new(k_px, focus).expect("a valid CoC model"), aperture: Aperture::Disk }
}

/// An opaque texture of repeating ramps: every blur changes it, none leaves [0, 1].
pub(crate) fn texture(width: usize, height: usize) -> Image {
    Image::from_fn(width, height, |x, y| {
        let v = ((x * 7 + y * 3) % 11) as f32 / 10.0;
        [v, 1.0 - v, 0.5 * v, 1.0]
    })
}
