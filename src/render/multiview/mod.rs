//! Depth of field by multiview synthesis (Lee, Eisemann & Seidel 2009): lens rays traced
//! through the layered height fields of a [`LayerStack`]. GPU path: `glsl/multiview_trace.comp`
//! ([`Multiview`]); CPU reference of the same math: [`render_multiview_cpu`].
//!
//! Thin-lens geometry. Put a pinhole camera at the lens centre with focal length `F` pixels,
//! focus at depth `z_f`, lens radius `E`. The lens ray of pixel `x` through the lens point
//! `E v` (`|v| <= 1`) passes through the in-focus point `P_f` that projects to `x`; at depth
//! `z` it is displaced from the centre ray by `R = E v (1 - z / z_f) = E v z (1/z - 1/z_f)`
//! (Lee et al. Eq. 2), which the pinhole projects to an image offset `F R / z =
//! F E (1/z - 1/z_f) v`. With `K = F E` and disparity `d = 1/z` (DESIGN.md: `K = (f/2N) *
//! (f/sensor) * width`), the ray meets a surface of disparity `d` at image position
//!
//! `x + v K (d - d_f)`   (signed: `d - d_f > 0` is nearer than focus).
//!
//! Read backwards, a source point `y` reaches the pixels `x = y - v K (d - d_f)`: an upright
//! copy of the aperture for far points and a mirrored one for near points, which is exactly
//! [`crate::camera::Aperture::to_aperture_coords`]; so `v` is in aperture coordinates and the
//! shared lens samples ([`crate::render::lens_samples`]) are used as they are.
//!
//! Per ray, layers are visited front to back. Within layer `l` the ray's disparity runs from
//! the layer's nearest to its farthest disparity; the height field (the layer's disparity,
//! empty pixels set to the far bound so rays pass through holes) is intersected by `steps`
//! rounds of false position (Sec. 4.3). At the hit the layer's mipmapped premultiplied RGBA is
//! read with a cone of diameter `spacing * K |d - d_f|` (approximate cone tracing, Sec. 4.4):
//! its alpha is the coverage `v_1`, and the ray goes on behind it with weight `1 - v_1` (the
//! paper's `v_1 c_1 + (1 - v_1) c_2` is premultiplied "over"). Layers with no coverage within
//! reach of the pixel's rays are skipped (min-depth culling; the paper's N-buffer query,
//! answered here by a summed-area table). Rays leaving the frame read the edge pixel.
mod gpu;
mod prepare;

pub use gpu::Multiview;

use rayon::prelude::*;

use crate::image::Image;
use crate::render::method::{InputKind, MethodInput, MethodSettings, MethodSpec, Renderer, Setting};
use crate::render::tiler::RenderOptions;
use crate::render::Lens;
use crate::stack::LayerStack;
use crate::vk::Context;
use crate::{Error, Result};
use prepare::Prepared;

/// Multiview in the registry: reads the lens sample count.
pub const METHOD: MethodSpec = MethodSpec {
    name: "multiview",
    label: "Multiview",
    summary: "Lens rays through the layers (Lee et al. 2009, Vulkan)",
    input: InputKind::Layers,
    uses_gpu: true,
    settings: &[Setting::Samples],
    prepare: renderer,
    differentiable: None,
    fast_on_cpu: crate::render::method::never_fast_on_cpu,
};

fn renderer(ctx: Option<&Context>) -> Result<Box<dyn Renderer>> {
    let gpu = ctx.map(Multiview::new).transpose()?;
    Ok(Box::new(move |input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, settings: &MethodSettings| {
        let stack = input.layers()?;
        let params = MultiviewParams::from_settings(settings);
        match &gpu {
            Some(gpu) => Ok(gpu.run_with(stack, lens, &params, options)?.0),
            None => render_multiview_cpu(stack, lens, &params),
        }
    }))
}

#[derive(Clone, Debug, PartialEq)]
pub struct MultiviewParams {
    /// Lens samples per pixel (rounded up to a square number of strata).
    pub samples: u32,
    /// Precomputed jittered sample sets; each pixel picks one by a hash of its coordinates.
    pub patterns: u32,
    pub seed: u32,
    /// False-position steps per layer (the paper: about 3).
    pub steps: u32,
    /// Scale of the cone diameter relative to the lens-sample spacing (0 = plain rays).
    pub cone_scale: f32,
    /// Skip layers with no coverage within reach (never changes the result).
    pub cull: bool,
}

impl MultiviewParams {
    /// What `--method multiview` and the benchmark use. Measured on `bench quality --quick` (mean
    /// PSNR): 64 samples 36.2 dB, 256 37.5, 512 37.7, 1024 37.8; cone tracing is worth +0.8 dB
    /// at 64 samples and nothing at 512, where it is kept (it never hurt).
    pub fn tuned() -> Self {
        Self { samples: 512, cone_scale: 1.0, ..Self::default() }
    }

    /// The tuned parameters with the lens sample count `settings` gives, the one setting
    /// multiview reads (the default settings give [`Self::tuned`]).
    pub fn from_settings(settings: &MethodSettings) -> Self {
        Self { samples: settings.samples, ..Self::tuned() }
    }
}

impl Default for MultiviewParams {
    fn default() -> Self {
        Self { samples: 64, patterns: 16, seed: 0, steps: 3, cone_scale: 1.0, cull: true }
    }
}

impl MultiviewParams {
    fn validate(&self) -> Result<()> {
        if self.steps > 32 {
            return Err(Error::invalid("multiview settings", format!("multiview steps must be at most 32, got {}", self.steps)));
        }
        if !(self.cone_scale.is_finite() && self.cone_scale >= 0.0) {
            return Err(Error::invalid("multiview settings", format!("cone scale must be a non-negative number, got {}", self.cone_scale)));
        }
        Ok(())
    }
}

/// Transmittance below which a ray stops (what is behind cannot change it visibly).
const OPAQUE_TRANSMITTANCE: f32 = 1.0e-4;

/// CPU reference of `glsl/multiview_trace.comp`.
pub fn render_multiview_cpu(stack: &LayerStack, lens: &Lens, params: &MultiviewParams) -> Result<Image> {
    let prepared = Prepared::with_planes(stack, lens, params)?;
    let mut out = Image::new(stack.width, stack.height);
    out.pixels.par_chunks_mut(stack.width.max(1)).enumerate().for_each(|(y, row)| {
        for (x, pixel) in row.iter_mut().enumerate() {
            *pixel = shade(&prepared, x, y);
        }
    });
    Ok(out)
}

fn shade(pr: &Prepared, x: usize, y: usize) -> [f32; 4] {
    let p = [x as f32, y as f32];
    let (mut sum, mut weight) = ([0.0f32; 4], 0.0f32);
    for s in pr.samples.set_for(x, y) {
        if s[2] <= 0.0 {
            continue;
        }
        let u = [s[0] * pr.k, s[1] * pr.k];
        let colour = trace(pr, p, u, y * pr.width + x);
        for c in 0..4 {
            sum[c] += s[2] * colour[c];
        }
        weight += s[2];
    }
    if weight > 0.0 {
        sum.map(|v| v / weight)
    } else {
        [0.0; 4]
    }
}

/// One lens ray, front to back through the layers: premultiplied RGBA it gathers.
fn trace(pr: &Prepared, p: [f32; 2], u: [f32; 2], pixel: usize) -> [f32; 4] {
    let mut acc = [0.0f32; 4];
    let mut transmittance = 1.0f32;
    for l in 0..pr.layers {
        let b = pr.bounds[l];
        if b[2] == 0.0 || (pr.cull && !pr.occupied(l, pixel)) {
            continue;
        }
        let t = intersect(pr, l, p, u, b[0], b[1]);
        let rel = t - pr.focus;
        let pos = [p[0] + u[0] * rel, p[1] + u[1] * rel];
        let diameter = pr.cone * rel.abs();
        let c = pr.sample_cone(l, pos, diameter);
        for k in 0..4 {
            acc[k] += transmittance * c[k];
        }
        transmittance *= 1.0 - c[3];
        if transmittance < OPAQUE_TRANSMITTANCE {
            break;
        }
    }
    acc
}

/// False-position search for the ray's hit in layer `l` between its far (`lo`) and near
/// (`hi`) disparity: `f(t) = height(ray(t)) - t` is <= 0 in front of the surface.
fn intersect(pr: &Prepared, l: usize, p: [f32; 2], u: [f32; 2], lo: f32, hi: f32) -> f32 {
    let f = |t: f32| pr.height(l, p, u, t) - t;
    let (mut ta, mut fa) = (hi, f(hi));
    if fa >= 0.0 {
        return ta;
    }
    let (mut tb, mut fb) = (lo, f(lo));
    for _ in 0..pr.steps {
        let t = ta + (tb - ta) * (fa / (fa - fb));
        let ft = f(t);
        if ft >= 0.0 {
            (tb, fb) = (t, ft);
        } else {
            (ta, fa) = (t, ft);
        }
    }
    tb
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--method multiview` without settings renders with the tuned parameters.
    #[test]
    fn default_settings_are_the_tuned_parameters() {
        assert_eq!(MultiviewParams::from_settings(&MethodSettings::default()), MultiviewParams::tuned());
    }
}
