//! Procedural aperture kernels: the cat's-eye (vignetted) aperture (the anamorphic ellipse is a
//! gauge shape, [`Aperture::Ellipse`], and the catadioptric ring has its own closed form,
//! [`Aperture::Ring`]). Each is a [`KernelImage`], which every renderer already samples over
//! the CoC disk and normalises exactly, so no shader needs to know these shapes.
//!
//! Aperture coordinates are image-oriented: `u` right, `v` down, unit radius = the CoC.
use crate::camera::{Aperture, KernelImage};
use crate::{Error, Result};

/// Side of a generated kernel image: fine enough that the bilinear rim is sub-pixel for CoCs
/// up to ~30 px, small enough to upload with every render.
pub const KERNEL_SIZE: usize = 64;
/// Sub-samples per texel side: texels on a rim get their fractional coverage (anti-aliased).
const SUBSAMPLES: usize = 4;

/// A kernel whose texels are the mean of `mask` over 4x4 sub-samples, cut to the unit disk
/// (the renderers' support).
pub fn procedural(size: usize, mask: impl Fn(f32, f32) -> f32) -> Result<KernelImage> {
    let mut weights = Vec::with_capacity(size * size);
    let step = 2.0 / (size * SUBSAMPLES) as f32;
    for j in 0..size {
        for i in 0..size {
            let mut sum = 0.0f32;
            for sj in 0..SUBSAMPLES {
                for si in 0..SUBSAMPLES {
                    let u = -1.0 + ((i * SUBSAMPLES + si) as f32 + 0.5) * step;
                    let v = -1.0 + ((j * SUBSAMPLES + sj) as f32 + 0.5) * step;
                    if u * u + v * v <= 1.0 {
                        sum += mask(u, v);
                    }
                }
            }
            weights.push(sum / (SUBSAMPLES * SUBSAMPLES) as f32);
        }
    }
    KernelImage::from_weights(size, weights)
}

/// Weight of `aperture` at `(u, v)` (1 inside a disk or polygon, the ring's annulus, the
/// image for kernels).
fn base_weight(aperture: &Aperture, u: f32, v: f32) -> f32 {
    match aperture {
        Aperture::Kernel(kernel) => kernel.sample(u, v),
        other if other.gauge(u, v) <= 1.0 => other.weight(u, v),
        _ => 0.0,
    }
}

/// Optical vignetting: `base` clipped by a second unit disk shifted by `shift` (aperture
/// radii, toward the frame edge), the lens-shaped pupil an off-axis point sees. The result is
/// re-centred on its centroid, so blurred content is not displaced (and neighbouring regions
/// of a [`super::vignette`] render blend without doubled edges).
pub fn cats_eye(base: &Aperture, shift: [f32; 2]) -> Result<KernelImage> {
    let clipped = |u: f32, v: f32| {
        let (a, b) = (u - shift[0], v - shift[1]);
        if a * a + b * b <= 1.0 { base_weight(base, u, v) } else { 0.0 }
    };
    let c = centroid(&clipped)?;
    procedural(KERNEL_SIZE, |u, v| clipped(u + c[0], v + c[1]))
}

/// Weighted centroid of a mask over the unit square grid at the kernel's sub-sample pitch.
fn centroid(mask: &dyn Fn(f32, f32) -> f32) -> Result<[f32; 2]> {
    let n = KERNEL_SIZE * SUBSAMPLES;
    let (mut su, mut sv, mut sw) = (0.0f64, 0.0f64, 0.0f64);
    for j in 0..n {
        for i in 0..n {
            let u = -1.0 + (i as f32 + 0.5) * 2.0 / n as f32;
            let v = -1.0 + (j as f32 + 0.5) * 2.0 / n as f32;
            let w = mask(u, v) as f64;
            su += w * u as f64;
            sv += w * v as f64;
            sw += w;
        }
    }
    if sw <= 0.0 {
        return Err(Error::invalid("cats-eye", "cat's-eye vignetting is so strong that no light passes the aperture"));
    }
    Ok([(su / sw) as f32, (sv / sw) as f32])
}
