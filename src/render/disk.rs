//! Constant-radius disk convolution of an RGBA image: the first compute operation of the
//! platform, the exact per-layer blur of the layered oracle, and a building block of the
//! baselines. GPU path: `glsl/disk_blur.comp`; CPU reference: [`disk_blur_cpu`].
//!
//! The kernel is the *anti-aliased* disk: each tap weighs the fraction of its pixel square that
//! lies inside the circle of radius `r` (what a thin lens does to a fronto-parallel plane at
//! constant CoC, up to the pixel box filter). Taps falling outside the image are dropped and
//! the rest renormalised, so a constant image stays constant up to its borders.
use rayon::prelude::*;

use crate::camera::Aperture;
use crate::image::Image;
use crate::shaders;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context, Slot, TexelFormat};
use crate::Result;

/// Sub-samples per pixel side used to integrate the disk's coverage of a pixel square.
const COVERAGE_SUBSAMPLES: usize = 8;

/// A square kernel of side `2 * half_extent + 1`, row-major, weights summing to 1.
#[derive(Clone, Debug, PartialEq)]
pub struct DiskKernel {
    pub half_extent: usize,
    pub weights: Vec<f32>,
}

impl DiskKernel {
    /// Anti-aliased disk of `radius` pixels; a radius below half a pixel is (nearly) identity.
    pub fn new(radius: f32) -> Self {
        // The centre sub-samples lie 0.09 px from the centre, inside the smallest radius used
        // (1/8 px): the disk always covers something, and the identity is only a formality.
        Self::covering(radius, |px, py, r| if px * px + py * py <= r * r { 1.0 } else { 0.0 })
            .unwrap_or(Self { half_extent: 0, weights: vec![1.0] })
    }

    /// The anti-aliased image of `aperture` at CoC `radius` for a plane of signed relative
    /// disparity `relative_disparity`: mirrored when nearer than focus
    /// ([`Aperture::to_aperture_coords`]), polygons through their gauge, kernel images by
    /// [`Aperture::kernel_weight`] over the disk, as every renderer reads them. A disk is
    /// [`Self::new`], bit for bit.
    pub fn shaped(radius: f32, aperture: &Aperture, relative_disparity: f32) -> Self {
        if *aperture == Aperture::Disk {
            return Self::new(radius);
        }
        // A kernel image whose light falls between every sub-sample at this radius passes
        // nothing: the disk is the nearest shape that still conserves the layer's energy.
        Self::covering(radius, |px, py, r| {
            // Tap offset (source - output) -> the PSF offset (output - source).
            let (u, v) = Aperture::to_aperture_coords(-px, -py, relative_disparity);
            if aperture.gauge(u, v) <= r { aperture.kernel_weight(u, v, r) } else { 0.0 }
        })
        .unwrap_or_else(|| Self::new(radius))
    }

    /// A kernel whose taps weigh the mean of `weight(px, py, r)` over 8x8 sub-samples of their
    /// pixel square (`px, py`: sub-sample position relative to the centre tap), normalised;
    /// `None` when every weight is 0.
    fn covering(radius: f32, weight: impl Fn(f32, f32, f32) -> f32) -> Option<Self> {
        let radius = radius.max(0.0);
        let half_extent = (radius + 0.5).ceil() as usize;
        let side = 2 * half_extent + 1;
        let mut weights = vec![0.0f32; side * side];
        let n = COVERAGE_SUBSAMPLES;
        // A radius under one sub-sample would miss every sample: treat it as a point.
        let effective = radius.max(1.0 / n as f32);
        for (i, w) in weights.iter_mut().enumerate() {
            let dx = (i % side) as f32 - half_extent as f32;
            let dy = (i / side) as f32 - half_extent as f32;
            let mut inside = 0.0f32;
            for sy in 0..n {
                for sx in 0..n {
                    let px = dx - 0.5 + (sx as f32 + 0.5) / n as f32;
                    let py = dy - 0.5 + (sy as f32 + 0.5) / n as f32;
                    inside += weight(px, py, effective);
                }
            }
            *w = inside;
        }
        let total: f32 = weights.iter().sum();
        if total <= 0.0 {
            return None;
        }
        weights.iter_mut().for_each(|w| *w /= total);
        Some(Self { half_extent, weights })
    }

    pub fn side(&self) -> usize {
        2 * self.half_extent + 1
    }
}

/// CPU reference of `glsl/disk_blur.comp`: same taps, same order, same renormalisation.
pub fn disk_blur_cpu(image: &Image, kernel: &DiskKernel) -> Image {
    let (w, h) = (image.width as i64, image.height as i64);
    let side = kernel.side() as i64;
    let half = kernel.half_extent as i64;
    let mut out = Image::new(image.width, image.height);
    out.pixels.par_chunks_mut(image.width).enumerate().for_each(|(y, row)| {
        for (x, pixel) in row.iter_mut().enumerate() {
            let mut sum = [0.0f32; 4];
            let mut weight = 0.0f32;
            for ky in 0..side {
                let sy = y as i64 + ky - half;
                if sy < 0 || sy >= h {
                    continue;
                }
                for kx in 0..side {
                    let sx = x as i64 + kx - half;
                    let k = kernel.weights[(ky * side + kx) as usize];
                    if sx < 0 || sx >= w || k == 0.0 {
                        continue;
                    }
                    let p = image.get(sx as usize, sy as usize);
                    for c in 0..4 {
                        sum[c] += k * p[c];
                    }
                    weight += k;
                }
            }
            *pixel = sum.map(|s| if weight > 0.0 { s / weight } else { 0.0 });
        }
    });
    out
}

/// Push constants of `glsl/disk_blur.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct DiskBlurPush {
    width: i32,
    height: i32,
    half_extent: i32,
    pad: i32,
}
const _: () = assert!(std::mem::size_of::<DiskBlurPush>() == 16);

/// Bindings of `disk_blur.comp`: the source and the kernel as texels, the result.
pub const DISK_BLUR_SLOTS: [Slot; 3] = [Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float), Slot::Storage];

/// Disk convolution on the GPU: uploads the image and kernel, dispatches, reads back.
pub struct DiskBlur {
    ctx: Context,
    pipeline: ComputePipeline,
}

impl DiskBlur {
    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::with_slots(ctx, &shaders::DISK_BLUR, &DISK_BLUR_SLOTS, std::mem::size_of::<DiskBlurPush>())?;
        Ok(Self { ctx: ctx.clone(), pipeline })
    }

    pub fn run(&self, image: &Image, kernel: &DiskKernel) -> Result<Image> {
        let ctx = &self.ctx;
        let source = Buffer::from_slice(ctx, "disk_blur source", &image.pixels)?;
        let weights = Buffer::from_slice(ctx, "disk_blur kernel", &kernel.weights)?;
        let result = Buffer::zeroed(ctx, "disk_blur result", std::mem::size_of_val(image.pixels.as_slice()) as u64)?;
        let push = DiskBlurPush {
            width: image.width as i32,
            height: image.height as i32,
            half_extent: kernel.half_extent as i32,
            pad: 0,
        };
        let groups = self.pipeline.groups_for([image.width as u32, image.height as u32, 1]);
        let mut batch = CommandBatch::new(ctx)?;
        batch.dispatch(&self.pipeline, &[source.all(), weights.all(), result.all()], &push, groups)?;
        batch.submit_and_wait()?;
        let pixels: Vec<[f32; 4]> = result.read(ctx)?;
        Ok(Image { width: image.width, height: image.height, pixels })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_area_matches_disk_area() {
        // Unnormalised coverage sums to pi r^2 up to the sub-sampling error (~1 / n per edge px).
        for r in [2.0f32, 5.5, 17.0] {
            let k = DiskKernel::new(r);
            let nonzero = k.weights.iter().filter(|&&w| w > 0.0).count() as f32;
            let peak = k.weights.iter().cloned().fold(0.0, f32::max);
            let area = k.weights.iter().map(|w| w / peak).sum::<f32>();
            let expected = std::f32::consts::PI * r * r;
            assert!((area - expected).abs() < 0.02 * expected + 1.0, "r={r}: {area} vs {expected}");
            assert!(nonzero <= ((2.0 * r + 3.0) * (2.0 * r + 3.0)), "r={r}");
        }
    }

    #[test]
    fn shaped_kernels_draw_the_aperture_mirrored_for_near_planes() {
        let at = |k: &DiskKernel, dx: i64, dy: i64| {
            let half = k.half_extent as i64;
            k.weights[((dy + half) * k.side() as i64 + dx + half) as usize]
        };
        // Ring 0.6 at r = 10: the centre tap is obstructed, a tap at 8 px is lit.
        let ring = DiskKernel::shaped(10.0, &Aperture::parse("ring:0.6").unwrap(), -0.5);
        assert!(at(&ring, 0, 0) == 0.0 && at(&ring, 8, 0) > 0.0);
        // A triangle with a vertex toward -u (rotation 0: the first edge's normal points +u):
        // a far plane draws it upright, a near one mirrored through the centre.
        let triangle = Aperture::polygon(3, 0.0, 0.0).unwrap();
        let (far, near) = (DiskKernel::shaped(10.0, &triangle, -0.5), DiskKernel::shaped(10.0, &triangle, 0.5));
        // Taps at (+-7, 0) relative to the output are sources whose PSF offset is (-+7, 0):
        // the far PSF reaches 10 px toward -u (vertex) and 5 px toward +u (edge).
        assert!(at(&far, 7, 0) > 0.0 && at(&far, -7, 0) == 0.0, "far: upright");
        assert!(at(&near, -7, 0) > 0.0 && at(&near, 7, 0) == 0.0, "near: mirrored");
        for k in [&ring, &far, &near] {
            // Normalised (the layer's energy is kept): f32 sum of a few hundred weights.
            assert!((k.weights.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        }
        assert_eq!(DiskKernel::shaped(6.3, &Aperture::Disk, 0.5), DiskKernel::new(6.3), "a disk is the disk kernel");
    }

    #[test]
    fn zero_radius_is_identity() {
        let img = Image::from_fn(7, 5, |x, y| [x as f32, y as f32, 1.0, 0.5]);
        assert_eq!(disk_blur_cpu(&img, &DiskKernel::new(0.0)), img);
    }

    #[test]
    fn constant_image_stays_constant_including_borders() {
        let img = Image::filled(20, 13, [0.25, 0.5, 4.0, 1.0]);
        let out = disk_blur_cpu(&img, &DiskKernel::new(6.3));
        for p in &out.pixels {
            for c in 0..4 {
                // Renormalisation by the in-image weight: exact up to f32 rounding.
                assert!((p[c] - img.pixels[0][c]).abs() < 1e-5 * img.pixels[0][c].abs().max(1.0));
            }
        }
    }
}
