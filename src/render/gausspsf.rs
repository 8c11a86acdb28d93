//! GaussPSF baseline (Gur & Wolf 2019): the differentiable renderer depth-from-defocus work
//! used before Dr.Bokeh, kept as the comparison point of the paper's Tables 2-3.
//!
//! Model, per layer and without any occlusion inside a layer: every source pixel `y`
//! (premultiplied RGBA `c_y`) is spread by a normalised Gaussian
//! `k_y(o) = exp(-|o|^2 / 2 s_y^2) / Z(s_y)` over a square window of half-width `R`, where
//! - `s_y = sqrt((c r_y)^2 + s0^2)` with `r_y = K (d_y - d_f)` the CoC radius: with the
//!   default `c = 1/2`, `r / 2` is the per-axis standard deviation of a uniform disk of radius
//!   `r`, so the Gaussian has the disk's second moment; the floor `s0` keeps `s` smooth (and
//!   positive) through focus.
//! - `Z(s)` sums the Gaussian over the *discrete, truncated* window, so each splat carries
//!   exactly `c_y` (light leaving the image border is lost, as it is for a crop);
//! - `R = min(ceil(truncation * max s), max_window)`, set per call and per layer from the
//!   widest splat that carries anything (transparent, colourless pixels add nothing).
//!
//! Each splat's Gaussian is separable, so it is stored as one axis table `exp(-i^2/2s^2)/z1`
//! (`Z = z1^2`) and a tap costs two lookups instead of an `exp`.
//!
//! Layers are blurred independently and composited front to back with `over` (each blurred
//! layer's alpha hides what is behind it). We chose `over` rather than an alpha-normalised sum
//! because the stacks we fit hold complete back layers behind the front ones: a sum would
//! average a sharp subject with the background it hides.
//!
//! Both passes are gathers (one owner per output value, deterministic): the forward gathers
//! sources into each output pixel; the backward gathers output gradients into each source.
//! The math runs in f64 so finite differences of the forward can check the backward tightly.
//!
//! Registered as the method `gausspsf` ([`METHOD`]): both passes run on the CPU (there is no
//! shader), the forward for `lensblur render`, the backward for `grad` and `fit-depth`. A
//! Gaussian has no aperture shape, so the forward refuses any aperture but the disk.
use rayon::prelude::*;

use crate::camera::{Aperture, CocModel};
use crate::image::Image;
use crate::render::grad::{Differentiable, LayerGradients, StackGradients};
use crate::render::method::{InputKind, MethodInput, MethodSettings, MethodSpec};
use crate::render::tiler::RenderOptions;
use crate::render::Lens;
use crate::stack::{Layer, LayerStack};
use crate::{Error, Result};

/// GaussPSF in the registry: CPU only, differentiable. Its soft Gaussian has no step to leak,
/// so both [`crate::render::grad::Slope`]s get the same exact gradient.
pub const METHOD: MethodSpec = MethodSpec {
    name: "gausspsf",
    label: "GaussPSF",
    summary: "Gaussian blur per layer composited over, no occlusion within a layer (Gur & Wolf 2019, CPU)",
    input: InputKind::Layers,
    uses_gpu: false,
    settings: &[],
    prepare: |_| Ok(Box::new(|input: MethodInput<'_>, lens: &Lens, _: &RenderOptions, _: &MethodSettings| render(input.layers()?, lens))),
    differentiable: Some(|_, _| Ok(Box::new(GaussPsf::default()))),
    fast_on_cpu: crate::render::method::never_fast_on_cpu,
};

/// The forward pass of the default [`GaussPsf`], for `lensblur render`.
fn render(stack: &LayerStack, lens: &Lens) -> Result<Image> {
    if lens.aperture != Aperture::Disk {
        return Err(Error::unsupported(
            "gausspsf blurs with a Gaussian, which has no aperture shape: it renders the disk aperture only (the default)",
        ));
    }
    GaussPsf::default().forward(stack, lens)
}

type Px = [f64; 4];

/// The GaussPSF renderer and its few knobs. The aperture shape is ignored (a Gaussian has none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussPsf {
    /// `c` in `s = sqrt((c r)^2 + s0^2)`; 0.5 matches the disk's second moment.
    pub sigma_per_radius: f64,
    /// `s0`: smallest standard deviation in pixels (an in-focus pixel is spread this much).
    pub sigma_floor: f64,
    /// The window reaches this many standard deviations of the widest splat.
    pub truncation: f64,
    /// Upper bound on the window half-width (cost grows with its square).
    pub max_window: usize,
}

impl Default for GaussPsf {
    /// `c = 0.5` (moment match); `s0 = 0.3` keeps 98% of an in-focus pixel in place; 3 sigma
    /// holds 99.7% of each axis.
    fn default() -> Self {
        Self {
            sigma_per_radius: 0.5,
            sigma_floor: 0.3,
            truncation: 3.0,
            max_window: 48,
        }
    }
}

/// One source pixel's splat, everything the two gathers need.
#[derive(Clone, Copy, Debug, Default)]
struct Splat {
    colour: Px,
    sigma: f64,
    /// `Z'(s) / Z(s)`.
    dlog_z: f64,
    /// `ds / dr`.
    dsigma_dr: f64,
}

impl GaussPsf {
    fn validate(&self, stack: &LayerStack) -> Result<()> {
        if !(self.sigma_per_radius.is_finite() && self.sigma_per_radius > 0.0) {
            return Err(Error::invalid("gausspsf settings", format!("GaussPSF sigma per radius must be positive, got {}", self.sigma_per_radius)));
        }
        if !(self.sigma_floor.is_finite() && self.sigma_floor > 0.0) {
            return Err(Error::invalid("gausspsf settings", format!(
                "GaussPSF sigma floor must be positive, got {}",
                self.sigma_floor
            )));
        }
        if !(self.truncation.is_finite() && self.truncation > 0.0) {
            return Err(Error::invalid("gausspsf settings", format!(
                "GaussPSF truncation must be positive, got {}",
                self.truncation
            )));
        }
        if stack.layers.is_empty() || stack.width == 0 || stack.height == 0 {
            return Err(Error::data("GaussPSF needs a non-empty stack"));
        }
        Ok(())
    }

    fn sigma(&self, r: f64) -> f64 {
        let c = self.sigma_per_radius;
        (c * c * r * r + self.sigma_floor * self.sigma_floor).sqrt()
    }

    /// Window half-width for the widest splat of the layer that carries anything.
    fn window(&self, layer: &Layer, coc: &CocModel) -> usize {
        let r = layer
            .rgba
            .pixels
            .iter()
            .zip(&layer.disparity)
            .filter(|(p, _)| **p != [0.0; 4])
            .fold(0.0f32, |m, (_, &d)| m.max(coc.radius(d)));
        let reach = (self.truncation * self.sigma(r as f64)).ceil();
        (reach.max(1.0) as usize).min(self.max_window.max(1))
    }

    fn splats(&self, layer: &Layer, coc: &CocModel) -> LayerSplats {
        let window = self.window(layer, coc);
        let (k, focus) = (coc.k_px as f64, coc.focus_disparity as f64);
        let (splats, tables): (Vec<Splat>, Vec<Vec<f64>>) = layer
            .rgba
            .pixels
            .par_iter()
            .zip(&layer.disparity)
            .map(|(c, &d)| {
                let r = k * (d as f64 - focus);
                let sigma = self.sigma(r);
                let (z1, dz1) = axis_sums(sigma, window);
                let inv_two_var = 0.5 / (sigma * sigma);
                let table = (0..=window).map(|i| (-((i * i) as f64) * inv_two_var).exp() / z1).collect();
                let splat = Splat {
                    colour: c.map(|v| v as f64),
                    sigma,
                    dlog_z: 2.0 * dz1 / z1,
                    dsigma_dr: self.sigma_per_radius * self.sigma_per_radius * r / sigma,
                };
                (splat, table)
            })
            .unzip();
        LayerSplats { window, splats, tables: tables.concat() }
    }
}

/// One layer's splats and their axis tables (`window + 1` entries per source pixel).
struct LayerSplats {
    window: usize,
    splats: Vec<Splat>,
    tables: Vec<f64>,
}

impl LayerSplats {
    #[inline]
    fn table(&self, i: usize) -> &[f64] {
        &self.tables[i * (self.window + 1)..(i + 1) * (self.window + 1)]
    }
}

/// `sum_i exp(-i^2 / 2 s^2)` over `i in [-R, R]` and its derivative in `s`; the 2-D
/// normaliser is the square of the first.
fn axis_sums(sigma: f64, window: usize) -> (f64, f64) {
    let inv_two_var = 0.5 / (sigma * sigma);
    let (mut z, mut dz) = (1.0, 0.0);
    for i in 1..=window {
        let i2 = (i * i) as f64;
        let e = (-i2 * inv_two_var).exp();
        z += 2.0 * e;
        dz += 2.0 * e * i2 / (sigma * sigma * sigma);
    }
    (z, dz)
}

/// Forward gather of one layer: every output pixel sums the splats reaching it.
fn blur_layer(layer: &LayerSplats, width: usize, height: usize) -> Vec<Px> {
    let mut out = vec![[0.0; 4]; width * height];
    let r = layer.window as i64;
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let y = y as i64;
        for (x, pixel) in row.iter_mut().enumerate() {
            let x = x as i64;
            for sy in (y - r).max(0)..=(y + r).min(height as i64 - 1) {
                for sx in (x - r).max(0)..=(x + r).min(width as i64 - 1) {
                    let i = sy as usize * width + sx as usize;
                    let s = &layer.splats[i];
                    if s.colour == [0.0; 4] {
                        continue;
                    }
                    let table = layer.table(i);
                    let k = table[(x - sx).unsigned_abs() as usize] * table[(y - sy).unsigned_abs() as usize];
                    for (p, c) in pixel.iter_mut().zip(s.colour) {
                        *p += k * c;
                    }
                }
            }
        }
    });
    out
}

/// Front-to-back `over` of the blurred layers at one pixel.
fn over(blurred: &[Vec<Px>], i: usize) -> Px {
    let (mut out, mut transmittance) = ([0.0; 4], 1.0);
    for layer in blurred {
        let b = layer[i];
        for c in 0..4 {
            out[c] += transmittance * b[c];
        }
        transmittance *= 1.0 - b[3];
    }
    out
}

/// dL/d(blurred layer) from dL/d(output): `out = B_0 + (1 - A_0) (B_1 + (1 - A_1) (...))`.
fn over_adjoint(blurred: &[Vec<Px>], grad: &Image) -> Vec<Vec<Px>> {
    let n = blurred.len();
    let per_pixel: Vec<Vec<Px>> = (0..grad.pixels.len())
        .into_par_iter()
        .map(|i| {
            let g = grad.pixels[i].map(|v| v as f64);
            let mut behind = [0.0; 4]; // composite of the layers behind the current one
            let mut grads = vec![[0.0; 4]; n];
            for l in (0..n).rev() {
                let transmittance: f64 = blurred[..l].iter().map(|b| 1.0 - b[i][3]).product();
                let g_behind: f64 = (0..4).map(|c| g[c] * behind[c]).sum();
                grads[l] = g.map(|v| transmittance * v);
                grads[l][3] -= transmittance * g_behind;
                let b = blurred[l][i];
                behind = std::array::from_fn(|c| b[c] + (1.0 - b[3]) * behind[c]);
            }
            grads
        })
        .collect();
    (0..n)
        .map(|l| per_pixel.iter().map(|g| g[l]).collect())
        .collect()
}

/// Gradients of one source pixel: dL/d(colour) and dL/d(sigma).
fn splat_backward(layer: &LayerSplats, grad: &[Px], (width, height): (usize, usize), (x, y): (i64, i64)) -> (Px, f64) {
    let i = y as usize * width + x as usize;
    let (s, table) = (&layer.splats[i], layer.table(i));
    let (r, sigma3) = (layer.window as i64, s.sigma * s.sigma * s.sigma);
    let (mut d_colour, mut d_sigma) = ([0.0; 4], 0.0);
    for ty in (y - r).max(0)..=(y + r).min(height as i64 - 1) {
        let ey = table[(ty - y).unsigned_abs() as usize];
        for tx in (x - r).max(0)..=(x + r).min(width as i64 - 1) {
            let k = ey * table[(tx - x).unsigned_abs() as usize];
            let g = grad[ty as usize * width + tx as usize];
            for c in 0..4 {
                d_colour[c] += k * g[c];
            }
            let o2 = ((tx - x) * (tx - x) + (ty - y) * (ty - y)) as f64;
            let g_dot_c: f64 = (0..4).map(|c| g[c] * s.colour[c]).sum();
            d_sigma += g_dot_c * k * (o2 / sigma3 - s.dlog_z);
        }
    }
    (d_colour, d_sigma)
}

/// Backward gather of one layer: its gradients and its share of dL/dK, dL/d(focus).
fn layer_backward(splats: &LayerSplats, layer: &Layer, grad: &[Px], coc: &CocModel) -> (LayerGradients, f64, f64) {
    let (width, height) = (layer.rgba.width, layer.rgba.height);
    let (k, focus) = (coc.k_px as f64, coc.focus_disparity as f64);
    // Per row: its gradients and its partial sums of dL/dK and dL/d(focus).
    type Row = (Vec<[f32; 4]>, Vec<f32>, f64, f64);
    let rows: Vec<Row> = (0..height)
        .into_par_iter()
        .map(|y| {
            let (mut rgba, mut disparity, mut dk, mut dfocus) = (
                Vec::with_capacity(width),
                Vec::with_capacity(width),
                0.0,
                0.0,
            );
            for x in 0..width {
                let i = y * width + x;
                let (d_colour, d_sigma) = splat_backward(splats, grad, (width, height), (x as i64, y as i64));
                let d_r = d_sigma * splats.splats[i].dsigma_dr;
                rgba.push(d_colour.map(|v| v as f32));
                disparity.push((d_r * k) as f32);
                dk += d_r * (layer.disparity[i] as f64 - focus);
                dfocus -= d_r * k;
            }
            (rgba, disparity, dk, dfocus)
        })
        .collect();
    let mut out = LayerGradients::default();
    let (mut dk, mut dfocus) = (0.0, 0.0);
    for (rgba, disparity, row_dk, row_dfocus) in rows {
        out.rgba.extend(rgba);
        out.disparity.extend(disparity);
        dk += row_dk;
        dfocus += row_dfocus;
    }
    (out, dk, dfocus)
}

/// The state both passes start from.
struct Blurred {
    /// Per layer.
    splats: Vec<LayerSplats>,
    /// Per layer, per output pixel.
    layers: Vec<Vec<Px>>,
}

impl GaussPsf {
    /// Splats and blurred layers at (`stack`, `lens`), shared by both passes.
    fn blur_all(&self, stack: &LayerStack, lens: &Lens) -> Result<Blurred> {
        self.validate(stack)?;
        let splats: Vec<LayerSplats> = stack.layers.iter().map(|l| self.splats(l, &lens.coc)).collect();
        let layers = splats.iter().map(|s| blur_layer(s, stack.width, stack.height)).collect();
        Ok(Blurred { splats, layers })
    }
}

impl GaussPsf {
    /// The forward pass before rounding to f32 (finite-difference tests need the precision).
    fn forward_f64(&self, stack: &LayerStack, lens: &Lens) -> Result<Vec<Px>> {
        let blurred = self.blur_all(stack, lens)?;
        Ok((0..stack.width * stack.height)
            .into_par_iter()
            .map(|i| over(&blurred.layers, i))
            .collect())
    }
}

impl Differentiable for GaussPsf {
    fn forward(&self, stack: &LayerStack, lens: &Lens) -> Result<Image> {
        let pixels = self
            .forward_f64(stack, lens)?
            .into_iter()
            .map(|p| p.map(|v| v as f32))
            .collect();
        Ok(Image {
            width: stack.width,
            height: stack.height,
            pixels,
        })
    }

    fn backward(
        &self,
        stack: &LayerStack,
        lens: &Lens,
        grad_output: &Image,
    ) -> Result<StackGradients> {
        if (grad_output.width, grad_output.height) != (stack.width, stack.height) {
            return Err(Error::data(format!(
                "output gradient is {}x{} but the stack is {}x{}",
                grad_output.width, grad_output.height, stack.width, stack.height
            )));
        }
        let blurred = self.blur_all(stack, lens)?;
        let layer_grads = over_adjoint(&blurred.layers, grad_output);
        let mut out = StackGradients::default();
        for ((layer, splats), grad) in stack.layers.iter().zip(&blurred.splats).zip(&layer_grads) {
            let (g, dk, dfocus) = layer_backward(splats, layer, grad, &lens.coc);
            out.layers.push(g);
            out.k_px += dk;
            out.focus_disparity += dfocus;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Method;

    use crate::render::test_inputs::disk_lens as lens;

    /// `--method gausspsf` renders the forward pass of the default model, on the CPU, and
    /// refuses an aperture shape it cannot draw instead of drawing a Gaussian.
    #[test]
    fn the_registered_method_renders_the_forward_pass_and_refuses_shaped_apertures() {
        let stack = random_stack(9, 7, 2, 3);
        let method = Method::GaussPsf;
        assert!(!method.uses_gpu() && method.is_differentiable());
        let rendered = method.render(None, &stack, &lens(3.0, 0.5)).unwrap();
        assert_eq!(rendered, GaussPsf::default().forward(&stack, &lens(3.0, 0.5)).unwrap());
        let ring = Lens { aperture: Aperture::Ring { inner: 0.5 }, ..lens(3.0, 0.5) };
        let error = method.render(None, &stack, &ring).unwrap_err().to_string();
        assert!(error.contains("disk aperture only"), "{error}");
    }

    /// Deterministic pseudo-random numbers in [0, 1).
    fn noise(seed: u64) -> impl FnMut() -> f32 {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    fn random_stack(width: usize, height: usize, layers: usize, seed: u64) -> LayerStack {
        let mut rand = noise(seed);
        let layers = (0..layers)
            .map(|l| {
                let rgba = Image::from_fn(width, height, |_, _| {
                    let a = 0.2 + 0.8 * rand();
                    [a * rand(), a * rand(), a * rand(), a]
                });
                let disparity = (0..width * height).map(|_| 0.1 + 0.8 * rand()).collect();
                Layer {
                    name: format!("l{l}"),
                    rgba,
                    disparity,
                }
            })
            .collect();
        LayerStack {
            width,
            height,
            layers,
        }
    }

    /// L = sum(weights . render), in f64.
    fn weighted_sum(stack: &LayerStack, lens: &Lens, weights: &Image) -> f64 {
        let out = GaussPsf::default().forward_f64(stack, lens).unwrap();
        out.iter()
            .zip(&weights.pixels)
            .map(|(o, w)| (0..4).map(|c| o[c] * w[c] as f64).sum::<f64>())
            .sum()
    }

    /// Central difference of `L` along one f32 input, divided by the step actually taken
    /// (f32 rounding of `v +- h` would otherwise bias it).
    fn central_difference(
        stack: &LayerStack,
        lens: &Lens,
        weights: &Image,
        set: impl Fn(&mut LayerStack, &mut Lens, f32) -> f32,
    ) -> f64 {
        let h = 1e-4;
        let (mut s, mut l) = (stack.clone(), lens.clone());
        let up = set(&mut s, &mut l, h) as f64;
        let f_up = weighted_sum(&s, &l, weights);
        let (mut s, mut l) = (stack.clone(), lens.clone());
        let down = set(&mut s, &mut l, -h) as f64;
        (f_up - weighted_sum(&s, &l, weights)) / (up - down)
    }

    #[test]
    fn backward_matches_finite_differences() {
        // K = 6 over disparities 0.1..0.9 gives sigmas from the floor up to ~1.4 px (window 5).
        let (stack, lens) = (random_stack(9, 7, 2, 1), lens(6.0, 0.45));
        let mut rand = noise(2);
        let weights = Image::from_fn(9, 7, |_, _| {
            [rand() - 0.5, rand() - 0.5, rand() - 0.5, rand() - 0.5]
        });
        let grads = GaussPsf::default()
            .backward(&stack, &lens, &weights)
            .unwrap();
        // Central differences with h = 1e-4 on a smooth f64 forward leave ~3e-7 relative
        // truncation error and the gradients are stored as f32 (~1e-7): 2e-6 sits above both
        // and far below any real mistake (a wrong term is off by O(1)).
        let scale = 1.0f64.max(grads.k_px.abs());
        let check = |analytic: f64, fd: f64, what: &str| {
            assert!(
                (analytic - fd).abs() <= 2e-6 * scale.max(fd.abs()),
                "{what}: analytic {analytic} vs fd {fd}"
            );
        };
        for l in 0..2 {
            for i in 0..stack.width * stack.height {
                let fd = central_difference(&stack, &lens, &weights, |s, _, h| {
                    let v = s.layers[l].disparity[i];
                    s.layers[l].disparity[i] = v + h;
                    s.layers[l].disparity[i]
                });
                check(
                    grads.layers[l].disparity[i] as f64,
                    fd,
                    &format!("disparity l{l} i{i}"),
                );
                for c in 0..4 {
                    let fd = central_difference(&stack, &lens, &weights, |s, _, h| {
                        s.layers[l].rgba.pixels[i][c] += h;
                        s.layers[l].rgba.pixels[i][c]
                    });
                    check(
                        grads.layers[l].rgba[i][c] as f64,
                        fd,
                        &format!("rgba l{l} i{i} c{c}"),
                    );
                }
            }
        }
        let fd_k = central_difference(&stack, &lens, &weights, |_, l, h| {
            l.coc.k_px += h;
            l.coc.k_px
        });
        check(grads.k_px, fd_k, "K");
        let fd_focus = central_difference(&stack, &lens, &weights, |_, l, h| {
            l.coc.focus_disparity += h;
            l.coc.focus_disparity
        });
        check(grads.focus_disparity, fd_focus, "focus");
    }

    #[test]
    fn flat_colour_is_preserved_away_from_borders() {
        // Normalising over the discrete window makes every splat carry exactly its colour, so
        // equal splats tile to a constant.
        let mut stack = random_stack(24, 20, 1, 3);
        let colour = [0.3, 0.5, 0.2, 1.0];
        stack.layers[0].rgba = Image::filled(24, 20, colour);
        stack.layers[0].disparity.iter_mut().for_each(|d| *d = 0.9);
        let lens = lens(4.0, 0.5);
        let renderer = GaussPsf::default();
        let window = renderer.window(&stack.layers[0], &lens.coc);
        let out = renderer.forward_f64(&stack, &lens).unwrap();
        for y in window..20 - window {
            for x in window..24 - window {
                let p = out[y * 24 + x];
                assert!(
                    (0..4).all(|c| (p[c] - colour[c] as f64).abs() < 1e-12),
                    "({x}, {y}): {p:?}"
                );
            }
        }
    }

    #[test]
    fn blur_width_follows_the_coc_radius() {
        // A point at CoC radius r spreads with per-axis variance r^2/4 + s0^2 (disk's moment).
        let mut stack = random_stack(41, 41, 1, 4);
        stack.layers[0].rgba = Image::new(41, 41);
        stack.layers[0].rgba.set(20, 20, [1.0, 1.0, 1.0, 1.0]);
        stack.layers[0].disparity.iter_mut().for_each(|d| *d = 1.5);
        let lens = lens(8.0, 0.5); // r = 8 px, sigma = 4.01, window 13 px: inside the image
        let out = GaussPsf::default().forward_f64(&stack, &lens).unwrap();
        let (sum, var_x) = out.iter().enumerate().fold((0.0, 0.0), |(s, v), (i, p)| {
            let dx = (i % 41) as f64 - 20.0;
            (s + p[0], v + p[0] * dx * dx)
        });
        assert!((sum - 1.0).abs() < 1e-12, "energy {sum}");
        // Truncation at 3 sigma removes ~3% of the variance of a Gaussian.
        let expected = 16.0 + 0.09;
        assert!(
            (var_x / expected - 1.0).abs() < 0.04 && var_x < expected,
            "variance {var_x} vs {expected}"
        );
    }

    #[test]
    fn opaque_in_focus_front_layer_hides_the_back() {
        let mut stack = random_stack(16, 16, 2, 5);
        stack.layers[0].rgba = Image::filled(16, 16, [0.9, 0.1, 0.1, 1.0]);
        stack.layers[0].disparity.iter_mut().for_each(|d| *d = 0.5);
        let out = GaussPsf::default()
            .forward(&stack, &lens(10.0, 0.5))
            .unwrap();
        for p in &out.pixels[16 * 4 + 4..16 * 4 + 12] {
            // In focus the front layer is exactly opaque away from borders; nothing shows through.
            assert!(
                (p[0] - 0.9).abs() < 1e-5 && (p[3] - 1.0).abs() < 1e-5,
                "{p:?}"
            );
        }
    }
}
