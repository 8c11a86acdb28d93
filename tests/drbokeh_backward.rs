//! The Dr.Bokeh f64 CPU backward pass against central finite differences of the f64 forward.
//!
//! Loss: `L = sum_x gout(x) . out(x)` with a fixed pseudo-random `gout`, so dL/d(input) is the
//! vector-Jacobian product the backward returns. The forward is evaluated in f64
//! (`render_cpu_terms(..).composite`); inputs are f32, so every step is a power of two that
//! f32 holds exactly at the perturbed value, and the difference quotient divides by the step
//! actually taken.
//!
//! Kinks: the forward is piecewise smooth (smoothstep edges, area-table nodes every 1/16 px,
//! `|s|` at focus, alpha > 0). Steps move a CoC radius by at most ~2e-5 px, and a central
//! difference is accurate to O(h^2) only if no kink lies within the step. Each difference is
//! taken at two steps (h and h/4): where they disagree the point straddles a kink and is
//! excluded (the count is asserted to be small); where they agree, the backward must match.
use lensblur::camera::{Aperture, CocModel, KernelImage};
use lensblur::image::Image;
use lensblur::render::drbokeh::backward_cpu::tile_reach_cpu;
use lensblur::render::drbokeh::{backward_cpu, render_cpu_params, BackwardOptions, CpuGradients, DrBokehCpu, Model, Params, Window};
use lensblur::render::grad::Differentiable;
use lensblur::render::Lens;
use lensblur::stack::{Layer, LayerStack};

const W: usize = 12;
const H: usize = 10;

fn hash(i: usize) -> f64 {
    let x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5851_F42D_4C95_7F2D;
    let x = (x ^ (x >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// Up to 5e-4 of disparity (3e-3 px of CoC): breaks the lattice of the slanted ramps, whose
/// f32 values otherwise fall within 1e-7 px of area-table nodes.
fn jitter(i: usize) -> f32 {
    5e-4 * hash(i + 7777) as f32
}

/// Three layers, CoC 1-4 px, K = 6, focus 0.5: a near blob with a soft alpha edge (alpha 1,
/// 0.6 ring, 0 outside), a near-focus layer (r 0.2-1.6 px: the in-focus occlusion ramp) with
/// holes, an opaque far layer. Disparities are slanted so radii vary pixel to pixel.
fn stack() -> LayerStack {
    let near = Layer {
        name: "near".into(),
        rgba: Image::from_fn(W, H, |x, y| {
            let d = ((x as f32 - 4.3).powi(2) + (y as f32 - 4.6).powi(2)).sqrt();
            let a = if d < 2.2 { 1.0 } else if d < 3.4 { 0.6 } else { 0.0 };
            [0.9 * a, (0.2 + 0.05 * x as f32) * a, 0.4 * a, a]
        }),
        disparity: (0..W * H).map(|i| 0.93 + 0.0071 * (i % W) as f32 - 0.0043 * (i / W) as f32 + jitter(i)).collect(),
    };
    let mid = Layer {
        name: "mid".into(),
        rgba: Image::from_fn(W, H, |x, y| {
            let a = if (x + 2 * y) % 7 == 0 { 0.0 } else if x > 7 { 0.75 } else { 1.0 };
            [(0.3 + 0.1 * (y % 3) as f32) * a, 0.7 * a, 2.0 * a, a]
        }),
        disparity: (0..W * H).map(|i| 0.531 + 0.0213 * (i % W) as f32 + 0.0017 * (i / W) as f32 + jitter(i + 1000)).collect(),
    };
    let far = Layer {
        name: "far".into(),
        rgba: Image::from_fn(W, H, |x, y| {
            let v = ((x * 5 + y * 3) % 7) as f32 / 7.0;
            [v, 0.5 - 0.3 * v, 3.0 * v + 0.1, 1.0]
        }),
        disparity: (0..W * H).map(|i| 0.13 + 0.0061 * (i % W) as f32 + 0.0037 * (i / W) as f32 + jitter(i + 2000)).collect(),
    };
    LayerStack::new(W, H, vec![near, mid, far]).unwrap()
}

fn lens(k_px: f32, focus: f32) -> Lens {
    Lens { coc: CocModel::new(k_px, focus).unwrap(), aperture: Aperture::Disk }
}

/// A 5x5 kernel image: uneven weights, so its bilinear gradient matters.
fn kernel_aperture() -> Aperture {
    let weights = (0..25).map(|i| 0.3 + ((i * 7) % 11) as f32 / 10.0).collect();
    Aperture::Kernel(KernelImage::from_weights(5, weights).unwrap())
}

fn grad_output() -> Image {
    Image::from_fn(W, H, |x, y| std::array::from_fn(|c| hash((y * W + x) * 4 + c) as f32))
}

/// `(L, sum |terms of L|)`: the second bounds the rounding error of L (~eps per term).
fn loss_with(stack: &LayerStack, params: Params, gout: &Image) -> (f64, f64) {
    let terms = render_cpu_params(stack, params, Window::Tiled);
    let mut sums = (0.0, 0.0);
    for (o, g) in terms.composite.iter().zip(&gout.pixels) {
        for c in 0..4 {
            sums.0 += o[c] * g[c] as f64;
            sums.1 += (o[c] * g[c] as f64).abs();
        }
    }
    sums
}

/// Central difference at step h: `(quotient, bound on its rounding error)`. `up`/`down` are
/// the perturbed values as stored, so the quotient divides by the step actually taken.
fn central(up: f64, down: f64, eval: &mut impl FnMut(f64) -> (f64, f64)) -> (f64, f64) {
    let ((l_up, abs_up), (l_down, abs_down)) = (eval(up), eval(down));
    let step = up - down;
    ((l_up - l_down) / step, 8.0 * f64::EPSILON * (abs_up + abs_down) / step)
}

/// A finite difference checked for smoothness: `(value, error bound)`, or None where the
/// quotients at steps h and h/4 disagree beyond O(h^2) truncation and rounding (a kink lies in
/// the step). `round` maps an f64 value to what the input can store.
fn fd(v0: f64, h: f64, round: impl Fn(f64) -> f64, mut eval: impl FnMut(f64) -> (f64, f64)) -> Option<(f64, f64)> {
    let (coarse, noise_coarse) = central(round(v0 + h), round(v0 - h), &mut eval);
    let (fine, noise_fine) = central(round(v0 + h / 4.0), round(v0 - h / 4.0), &mut eval);
    let bound = 1e-8 * fine.abs() + noise_coarse + noise_fine;
    ((coarse - fine).abs() <= bound).then_some((fine, noise_fine))
}

fn f32_round(v: f64) -> f64 {
    v as f32 as f64
}

struct Check {
    name: String,
    /// Largest error as a fraction of its tolerance.
    worst: f64,
    /// Largest relative error of the entries well above their rounding bound.
    worst_rel: f64,
    checked: usize,
    skipped: usize,
}

impl Check {
    fn new(name: &str) -> Self {
        Self { name: name.into(), worst: 0.0, worst_rel: 0.0, checked: 0, skipped: 0 }
    }

    fn add(&mut self, what: &str, analytic: f64, numeric: Option<(f64, f64)>) {
        let Some((numeric, noise)) = numeric else {
            self.skipped += 1;
            return;
        };
        // 1e-6 relative, plus the difference's own rounding bound for near-zero entries.
        let err = (analytic - numeric).abs();
        assert!(err <= 1e-6 * numeric.abs() + noise, "{}: {what}: backward {analytic:e} vs FD {numeric:e} (+-{noise:e})", self.name);
        self.worst = self.worst.max(err / (1e-6 * numeric.abs() + noise));
        if numeric.abs() > 1e3 * noise {
            self.worst_rel = self.worst_rel.max(err / numeric.abs());
        }
        self.checked += 1;
    }

    fn finish(&self, min_checked: usize) {
        eprintln!(
            "{}: {} checked, {} skipped at kinks, worst error {:.3} of tolerance, worst relative {:e}",
            self.name, self.checked, self.skipped, self.worst, self.worst_rel
        );
        assert!(self.checked >= min_checked && self.skipped * 10 <= self.checked, "{}: too few kink-free points", self.name);
    }
}

/// Test pixels: corners and borders, the near blob's alpha edge, holes of the mid layer, interior.
const PIXELS: [(usize, usize); 12] = [(0, 0), (11, 9), (11, 0), (0, 5), (6, 9), (4, 4), (6, 5), (2, 3), (1, 4), (7, 2), (7, 0), (9, 6)];

fn gradients(model: Model, options: BackwardOptions) -> CpuGradients {
    backward_cpu(&stack(), &lens(6.0, 0.5), model, options, &grad_output()).unwrap()
}

fn check_layer_inputs(model: Model, aperture: Aperture) {
    let (base, gout) = (stack(), grad_output());
    let lens = Lens { aperture, ..lens(6.0, 0.5) };
    let grads = backward_cpu(&base, &lens, model, BackwardOptions::exact(), &gout).unwrap();
    // Parameters once (the kernel's area table is costly); they depend on the stack only via
    // max_support, which bounds the tile dilation with a spare tile: steps here cannot matter.
    let params = Params::new(&base, &lens, model).unwrap();
    let name = format!("{model:?} {:?}", lens.aperture.gpu_params());
    let mut rgba = Check::new(&format!("{name} rgba"));
    let mut disparity = Check::new(&format!("{name} disparity"));
    for (l, layer_grads) in grads.layers.iter().enumerate() {
        for &(x, y) in &PIXELS {
            let i = y * W + x;
            for c in 0..4 {
                let v0 = base.layers[l].rgba.pixels[i][c] as f64;
                if c == 3 && v0 == 0.0 {
                    continue; // alpha > 0 gates a source: one-sided there
                }
                // L is linear in premultiplied colour (any step is exact up to rounding, so a
                // large one keeps rounding small); alpha enters W, V, O and the gate.
                let step = if c < 3 { 1.0 / 64.0 } else { 1.0 / 65536.0 };
                let numeric = fd(v0, step, f32_round, |v| {
                    let mut s = base.clone();
                    s.layers[l].rgba.pixels[i][c] = v as f32;
                    loss_with(&s, params.clone(), &gout)
                });
                rgba.add(&format!("layer {l} ({x},{y}) c{c}"), layer_grads.rgba[i][c], numeric);
            }
            // 2^-16 moves r by 9e-5 px: rounding stays ~1e-8 relative.
            let numeric = fd(base.layers[l].disparity[i] as f64, 1.0 / 65536.0, f32_round, |v| {
                let mut s = base.clone();
                s.layers[l].disparity[i] = v as f32;
                loss_with(&s, params.clone(), &gout)
            });
            disparity.add(&format!("layer {l} ({x},{y})"), layer_grads.disparity[i], numeric);
        }
    }
    rgba.finish(100);
    disparity.finish(25);
}

/// The scene with every alpha raised to at least 0.15: each pixel is then its own source, so
/// W >= 2e-3 everywhere (asserted) and the existence gate sits on its plateau. Its ramp
/// (W in [0, 1e-3]) has a third derivative ~1e10, which no step a scalar FD can take resolves.
fn covered_stack() -> LayerStack {
    let mut s = stack();
    for layer in &mut s.layers {
        for p in &mut layer.rgba.pixels {
            if p[3] < 0.15 {
                *p = [0.15 * 0.5, 0.15 * 0.25, 0.15, 0.15];
            }
        }
    }
    s
}

/// Smallest distance in px of any CoC radius to a C0 kink that moves with K and focus: the
/// area table's nodes (every 1/16 px, default model) and `|s|` at 0.
fn radius_kink_margin(stack: &LayerStack, lens: &Lens) -> f64 {
    let (k, f) = (lens.coc.k_px as f64, lens.coc.focus_disparity as f64);
    let radii = stack.layers.iter().flat_map(|l| l.disparity.iter().map(move |&d| (k * (d as f64 - f)).abs()));
    radii.map(|r| (r - (r * 16.0).round() / 16.0).abs()).fold(f64::INFINITY, f64::min)
}

fn check_scalars(model: Model) {
    let (base, gout, lens) = (covered_stack(), grad_output(), lens(6.0, 0.5));
    let params = Params::new(&base, &lens, model).unwrap();
    let terms = render_cpu_params(&base, params.clone(), Window::Tiled);
    let min_w = terms.layers.iter().flat_map(|l| l.cw.iter().map(|c| c[3])).fold(f64::INFINITY, f64::min);
    assert!(min_w > 2e-3, "gate ramp in the scene: W = {min_w}");
    // The steps below move radii by < 1e-6 px: keep C0 kinks 20x farther.
    let margin = radius_kink_margin(&base, &lens);
    assert!(margin > 2e-5, "a radius sits on a kink: {margin}");
    let grads = backward_cpu(&base, &lens, model, BackwardOptions::exact(), &gout).unwrap();
    let mut scalars = Check::new(&format!("{model:?} K/focus"));
    // K and the focus move every radius at once, in f64 through `params.lens`: these steps move
    // radii by < 1e-6 px, so a smoothstep edge in the step adds < 1e-6 of one pair's term.
    let k = fd(6.0, 1e-6, |v| v, |k| {
        let mut p = params.clone();
        p.lens.k_px = k;
        loss_with(&base, p, &gout)
    });
    scalars.add("K", grads.k_px, k);
    let f = fd(0.5, 1.5e-7, |v| v, |f| {
        let mut p = params.clone();
        p.lens.focus_disparity = f;
        loss_with(&base, p, &gout)
    });
    scalars.add("focus", grads.focus_disparity, f);
    eprintln!("{model:?}: dL/dK {:e} vs {k:?}, dL/dfocus {:e} vs {f:?}", grads.k_px, grads.focus_disparity);
    scalars.finish(2);
    assert_eq!(scalars.skipped, 0, "K/focus straddle a kink: move the scene");
}

#[test]
fn backward_matches_finite_differences_for_layer_inputs_default_model() {
    check_layer_inputs(Model::DrBokeh, Aperture::Disk);
}

#[test]
fn backward_matches_finite_differences_for_layer_inputs_compat_model() {
    check_layer_inputs(Model::Compat, Aperture::Disk);
}

#[test]
fn backward_matches_finite_differences_for_polygon_ring_and_kernel_apertures() {
    // Polygon gauges do not depend on r; kernel weights do (sampled at p / (r + 1/2), faded
    // in over 0.5-1.5 px): the kernel's bilinear cells add kinks, which the guard skips.
    check_layer_inputs(Model::DrBokeh, Aperture::polygon(5, 10.0, 0.3).unwrap());
    check_layer_inputs(Model::DrBokeh, kernel_aperture());
    // The ring's obstruction edge moves with r (radius inner r): its own dK/dr term.
    check_layer_inputs(Model::DrBokeh, Aperture::ring(0.5).unwrap());
}

#[test]
fn backward_matches_finite_differences_for_k_and_focus() {
    for model in [Model::DrBokeh, Model::Compat] {
        check_scalars(model);
    }
}



#[test]
fn leaky_gradients_differ_only_through_saturated_soft_steps() {
    for model in [Model::DrBokeh, Model::Compat] {
        let exact = gradients(model, BackwardOptions::exact());
        let leaky = gradients(model, BackwardOptions::leaky());
        // The leak only replaces dS/dr: colour and alpha gradients never see it.
        for (e, l) in exact.layers.iter().zip(&leaky.layers) {
            assert_eq!(e.rgba, l.rgba, "{model:?}: leak changed a colour/alpha gradient");
        }
        let changed = exact.layers.iter().zip(&leaky.layers).flat_map(|(e, l)| e.disparity.iter().zip(&l.disparity)).filter(|(a, b)| a != b).count();
        // Every pixel with r > 1/2 has plateau pairs (S = 1, S' = 0), so the leak shows.
        assert!(changed > 100, "{model:?}: leak changed only {changed} disparity gradients");
        assert_ne!(exact.k_px, leaky.k_px);
    }
}


#[test]
fn tile_reach_covers_every_receiver_window_holding_the_tile() {
    // 50x40 px: 4x3 tiles with ragged edges. Windows up to ceil(max_support) - 1 (what the
    // forward's dilation can produce); K = 40 makes max_support ~ 20 px.
    let (w, h) = (50, 40);
    let layer = Layer { name: "l".into(), rgba: Image::new(w, h), disparity: (0..w * h).map(|i| 0.5 + 0.5 * (i % 7) as f32 / 6.0).collect() };
    let stack = LayerStack::new(w, h, vec![layer]).unwrap();
    let params = Params::new(&stack, &lens(40.0, 0.5), Model::DrBokeh).unwrap();
    let max_h = params.max_support.ceil() as usize - 1;
    let windows: Vec<i32> = (0..12).map(|t| ((hash(t + 99).abs() * (max_h + 1) as f64) as usize).min(max_h) as i32).collect();
    let reach = tile_reach_cpu(&params, &windows);
    let tile = |x: usize, y: usize| (y / 16) * params.tiles_x + x / 16;
    let mut tight = vec![0i32; 12];
    for ry in 0..h {
        for rx in 0..w {
            let hw = windows[tile(rx, ry)];
            for sy in 0..h {
                for sx in 0..w {
                    let d = (rx as i32 - sx as i32).abs().max((ry as i32 - sy as i32).abs());
                    if d <= hw {
                        let t = tile(sx, sy);
                        assert!(d <= reach[t], "receiver ({rx},{ry}) holds ({sx},{sy}) at {d} > reach {}", reach[t]);
                        tight[t] = tight[t].max(hw);
                    }
                }
            }
        }
    }
    // And no wider than the largest window that actually holds a pixel of the tile.
    assert_eq!(reach, tight);
}

#[test]
fn backward_rejects_an_output_gradient_of_another_size() {
    let renderer = DrBokehCpu { model: Model::DrBokeh, options: BackwardOptions::exact() };
    let wrong = Image::new(W + 1, H);
    let err = renderer.backward(&stack(), &lens(6.0, 0.5), &wrong).unwrap_err();
    assert!(err.to_string().contains("13x10"), "{err}");
}

/// A textured layer 0.01 disparity in front of the focus (CoC 0.06 px with K = 6). Before
/// sources under a pixel were given the lens's blur (`math::coverage_radius`), its windows held
/// only its own pixels and the exact gradient w.r.t. its depth was ~1e-9: only the leaky
/// backward, whose margin reaches past the supports, moved a fit started near focus. Now the
/// 0.06 px source reaches its neighbours a little, as the lens does, and both gradients must
/// be clear; the leak adds to the exact one, it never removes it.
#[test]
fn gradients_reach_nearly_in_focus_layers() {
    let (w, h) = (12, 10);
    let texture = Image::from_fn(w, h, |x, y| {
        let v = 0.2 + 0.6 * hash(x * 31 + y * 7) as f32;
        [v, 1.0 - v, 0.5, 1.0]
    });
    let layer = Layer { name: "near-focus".into(), rgba: texture, disparity: vec![0.51; w * h] };
    let stack = LayerStack::new(w, h, vec![layer]).unwrap();
    let lens = lens(6.0, 0.5);
    let g = grad_output();
    let norm = |options| {
        let grads = DrBokehCpu { model: Model::DrBokeh, options }.backward(&stack, &lens, &g).unwrap();
        grads.layers[0].disparity.iter().map(|v| v.abs() as f64).sum::<f64>()
    };
    let (exact, leaky) = (norm(BackwardOptions::exact()), norm(BackwardOptions::leaky()));
    eprintln!("exact {exact}, leaky {leaky}");
    assert!(exact > 1e-2, "exact gradient {exact} must reach the nearly in-focus layer");
    assert!(leaky >= exact * 0.99, "leaky gradient {leaky} below the exact {exact}");
}

/// A vignetted aperture (one-pass `--cats-eye` of a disk, a straight-bladed polygon or the
/// ellipse) has a shape per receiver tile, which the backward's gauge paths do not take:
/// refused with a message, never a silently wrong gradient.
#[test]
fn backward_refuses_vignetted_apertures() {
    for base in [Aperture::Disk, Aperture::polygon(6, 0.0, 0.0).unwrap(), Aperture::anamorphic(1.8, 0.0).unwrap()] {
        let lens = Lens { aperture: Aperture::vignetted(&base, 0.6).unwrap(), ..lens(6.0, 0.5) };
        let error = backward_cpu(&stack(), &lens, Model::DrBokeh, BackwardOptions::exact(), &grad_output()).unwrap_err();
        assert!(error.to_string().contains("no backward pass"), "{base:?}: {error}");
    }
}
