//! f64 CPU reference of the Dr.Bokeh backward passes, shaped like the shaders:
//! `composite_pixel` is the body of `drbokeh_backward_composite.comp`, `own_pixel` of
//! `drbokeh_backward_own.comp`, `source_pixel` of `drbokeh_backward_source.comp`;
//! `tile_reach_cpu` is also what the GPU backward uploads (pass roles
//! in [`super::backward`]). Each function owns the values it returns: gathers only.
use rayon::prelude::*;

use super::backward::{check_inputs, pair_grad, vis_weight, BackwardOptions, Px};
use super::cpu::{clipped_window, render_cpu_terms, LayerTerms};
use super::{math, Model, Params, TILE};
use crate::image::Image;
use crate::render::grad::{Differentiable, LayerGradients, StackGradients};
use crate::render::Lens;
use crate::stack::{Layer, LayerStack};
use crate::Result;

/// The f64 CPU reference as a [`Differentiable`] renderer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DrBokehCpu {
    pub model: Model,
    pub options: BackwardOptions,
}

impl Differentiable for DrBokehCpu {
    fn forward(&self, stack: &LayerStack, lens: &Lens) -> Result<Image> {
        super::render_cpu(stack, lens, self.model)
    }

    fn backward(&self, stack: &LayerStack, lens: &Lens, grad_output: &Image) -> Result<StackGradients> {
        Ok(backward_cpu(stack, lens, self.model, self.options, grad_output)?.to_stack_gradients())
    }
}


/// dL/d(inputs) of one layer in f64, plus each pixel's share of dL/dK.
#[derive(Clone, Debug, PartialEq)]
pub struct CpuLayerGradients {
    pub rgba: Vec<[f64; 4]>,
    pub disparity: Vec<f64>,
    /// `rel g_s` per pixel: dL/dK is their sum.
    pub k_partial: Vec<f64>,
}

/// Every gradient of one backward pass in f64.
#[derive(Clone, Debug, PartialEq)]
pub struct CpuGradients {
    pub layers: Vec<CpuLayerGradients>,
    pub k_px: f64,
    pub focus_disparity: f64,
}

impl CpuGradients {
    pub fn to_stack_gradients(&self) -> StackGradients {
        StackGradients {
            layers: self
                .layers
                .iter()
                .map(|l| LayerGradients {
                    rgba: l.rgba.iter().map(|p| p.map(|v| v as f32)).collect(),
                    disparity: l.disparity.iter().map(|&v| v as f32).collect(),
                })
                .collect(),
            k_px: self.k_px,
            focus_disparity: self.focus_disparity,
        }
    }
}

/// Adjoints of one layer's forward intermediates: `cw = dL/d[C.rgb, W]`, `visibility = dL/dV`.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerAdjoint {
    pub cw: Vec<[f64; 4]>,
    pub visibility: Vec<f64>,
}

/// The vector-Jacobian product of [`super::render_cpu`] with `grad_output`.
pub fn backward_cpu(stack: &LayerStack, lens: &Lens, model: Model, options: BackwardOptions, grad_output: &Image) -> Result<CpuGradients> {
    check_inputs(stack, lens, grad_output)?;
    let terms = render_cpu_terms(stack, lens, model, options.window())?;
    let params = &terms.params;
    let adjoints = composite_backward_cpu(params, &terms.layers, grad_output);
    let layers: Vec<CpuLayerGradients> = stack
        .layers
        .iter()
        .zip(&terms.layers)
        .zip(&adjoints)
        .map(|((layer, forward), adjoint)| {
            let own = own_cpu(params, layer, &forward.window, adjoint, options);
            source_cpu(params, layer, &forward.window, adjoint, &own, options)
        })
        .collect();
    let k_px = layers.iter().flat_map(|l| &l.k_partial).sum();
    let focus_disparity = -layers.iter().flat_map(|l| &l.disparity).sum::<f64>();
    Ok(CpuGradients { layers, k_px, focus_disparity })
}

/// Pass 1 over every pixel: per layer adjoints.
pub fn composite_backward_cpu(params: &Params, layers: &[LayerTerms], grad_output: &Image) -> Vec<LayerAdjoint> {
    let n = params.width * params.height;
    let per_pixel: Vec<Vec<([f64; 4], f64)>> =
        (0..n).into_par_iter().map(|i| composite_pixel(params, layers, i, grad_output.pixels[i].map(|v| v as f64))).collect();
    (0..layers.len())
        .map(|l| LayerAdjoint { cw: per_pixel.iter().map(|p| p[l].0).collect(), visibility: per_pixel.iter().map(|p| p[l].1).collect() })
        .collect()
}

/// Reverse of `composite_pixel` in `cpu.rs`. With `G_l = gout . (C_l / W_l, 1)` and
/// `acc_l = v_l G_l + (1 - v_l) acc_{l+1}` (the composite from layer l back, seen from l),
/// `dL/dv_l = T_l (G_l - acc_{l+1})`: no division by `1 - v`, so opaque layers are fine.
fn composite_pixel(params: &Params, layers: &[LayerTerms], i: usize, gout: [f64; 4]) -> Vec<([f64; 4], f64)> {
    let mut fwd = Vec::with_capacity(layers.len()); // (T, v, gate, colour, G)
    let mut transmittance = 1.0f64;
    for terms in layers {
        let [c0, c1, c2, w] = terms.cw[i];
        let gate = if params.model == Model::DrBokeh { math::existence_gate(w) } else { 1.0 };
        let v = terms.visibility[i] * gate;
        let colour = if w > 0.0 { [c0 / w, c1 / w, c2 / w] } else { [0.0; 3] };
        let g = gout[0] * colour[0] + gout[1] * colour[1] + gout[2] * colour[2] + gout[3];
        fwd.push((transmittance, v, gate, colour, g));
        transmittance *= 1.0 - v;
    }
    let mut out = vec![([0.0f64; 4], 0.0f64); layers.len()];
    let mut acc = 0.0f64;
    for l in (0..layers.len()).rev() {
        let (t, v, gate, colour, g) = fwd[l];
        let w = layers[l].cw[i][3];
        let d_v = t * (g - acc);
        acc = v * g + (1.0 - v) * acc;
        let mut d_cw = [0.0f64; 4];
        if w > 0.0 {
            for c in 0..3 {
                let d_colour = t * v * gout[c];
                d_cw[c] = d_colour / w;
                d_cw[3] -= d_colour * colour[c] / w;
            }
        }
        let d_vis = match params.model {
            Model::DrBokeh => {
                d_cw[3] += d_v * layers[l].visibility[i] * math::d_existence_gate(w);
                d_v * gate
            }
            Model::Compat => d_v,
        };
        out[l] = (d_cw, d_vis);
    }
    out
}

/// Pass 2 of one layer: `[dL/dalpha_x, dL/ds_x, dL/drel_x, dL/dV / sum D]` per pixel x.
pub fn own_cpu(params: &Params, layer: &Layer, window: &[i32], adjoint: &LayerAdjoint, options: BackwardOptions) -> Vec<[f64; 4]> {
    (0..params.width * params.height)
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i % params.width) as i64, (i / params.width) as i64);
            let tile = (y as usize / TILE) * params.tiles_x + x as usize / TILE;
            own_pixel(params, layer, adjoint, options.leaky_slope, x, y, window[tile] as i64)
        })
        .collect()
}

/// Loops over x's forward window like `layer_pixel`, differentiating w.r.t. x's inputs.
fn own_pixel(params: &Params, layer: &Layer, adjoint: &LayerAdjoint, leak: f64, x: i64, y: i64, h: i64) -> [f64; 4] {
    let width = params.width as i64;
    let ix = (y * width + x) as usize;
    let dst = Px::new(&params.lens, layer.disparity[ix], layer.rgba.pixels[ix][3]);
    let [gc0, gc1, gc2, gw] = adjoint.cw[ix];
    let box_half = math::visibility_box_compat(dst.r);
    let (mut d_alpha, mut d_s, mut d_rel) = (0.0f64, 0.0f64, 0.0f64);
    // sum D, sum alpha D, sum D', sum alpha D' (D' = dD/dr_x), or the compat box count.
    let mut vis = [0.0f64; 4];
    for (ox, oy, iy) in clipped_window(params, x, y, h) {
        let p = layer.rgba.pixels[iy];
        let src = Px::new(&params.lens, layer.disparity[iy], p[3]);
        let (dx, dy) = (-ox as f64, -oy as f64);
        if p[3] > 0.0 {
            let a = gc0 * p[0] as f64 + gc1 * p[1] as f64 + gc2 * p[2] as f64 + gw * src.alpha;
            let pg = pair_grad(params, leak, dx, dy, &src, &dst, ox == 0 && oy == 0);
            d_alpha += a * pg.alpha_x;
            d_s += a * pg.s_x;
            d_rel += a * pg.rel_x;
        }
        match params.model {
            Model::DrBokeh => {
                let (d, d_d) = vis_weight(params, leak, dx, dy, &dst);
                vis = [vis[0] + d, vis[1] + src.alpha * d, vis[2] + d_d, vis[3] + src.alpha * d_d];
            }
            Model::Compat => {
                if ox.abs() <= box_half && oy.abs() <= box_half {
                    vis[0] += 1.0;
                }
            }
        }
    }
    let d_vis = adjoint.visibility[ix];
    if vis[0] <= 0.0 {
        return [d_alpha, d_s, d_rel, 0.0];
    }
    if params.model == Model::DrBokeh {
        // V = sum alpha D / sum D, so dV/dr_x = (sum alpha D' sum D - sum alpha D sum D') / (sum D)^2.
        let d_v_dr = (vis[3] * vis[0] - vis[1] * vis[2]) / (vis[0] * vis[0]);
        d_s += d_vis * d_v_dr * dst.sign();
    }
    [d_alpha, d_s, d_rel, d_vis / vis[0]]
}

/// Pass 3 of one layer: the final gradients of every pixel of `layer`.
pub fn source_cpu(
    params: &Params,
    layer: &Layer,
    window: &[i32],
    adjoint: &LayerAdjoint,
    own: &[[f64; 4]],
    options: BackwardOptions,
) -> CpuLayerGradients {
    let reach = tile_reach_cpu(params, window);
    let per_pixel: Vec<([f64; 4], f64, f64)> = (0..params.width * params.height)
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i % params.width) as i64, (i / params.width) as i64);
            let tile = (y as usize / TILE) * params.tiles_x + x as usize / TILE;
            source_pixel(params, layer, window, adjoint, own, options.leaky_slope, x, y, reach[tile] as i64)
        })
        .collect();
    CpuLayerGradients {
        rgba: per_pixel.iter().map(|p| p.0).collect(),
        disparity: per_pixel.iter().map(|p| p.1).collect(),
        k_partial: per_pixel.iter().map(|p| p.2).collect(),
    }
}

/// Per tile, the half-width of the square of receivers whose windows may hold a source of
/// the tile (the GPU backward's `tile_reach` buffer too): a receiver in tile U holds sources
/// up to `h_U` px away, so `reach_T = max { h_U : gap(U, T) <= h_U }`.
pub fn tile_reach_cpu(params: &Params, window: &[i32]) -> Vec<i32> {
    let (tiles_x, tiles_y) = (params.tiles_x as i64, params.tiles_y as i64);
    // Windows are at most ceil(max_support) - 1 px: tiles farther apart never see each other.
    let range = (params.max_support / TILE as f64).ceil() as i64 + 1;
    let gap = |k: i64| if k == 0 { 0 } else { k.abs() * TILE as i64 - (TILE as i64 - 1) };
    (0..window.len() as i64)
        .map(|t| {
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let mut reach = 0;
            for uy in (ty - range).max(0)..=(ty + range).min(tiles_y - 1) {
                for ux in (tx - range).max(0)..=(tx + range).min(tiles_x - 1) {
                    let h = window[(uy * tiles_x + ux) as usize];
                    if gap(ux - tx).max(gap(uy - ty)) <= h as i64 {
                        reach = reach.max(h);
                    }
                }
            }
            reach
        })
        .collect()
}

/// Source y = (x, y) over every receiver whose window holds it: `(dL/dP.rgba, dL/dd, rel g_s)`.
#[allow(clippy::too_many_arguments)]
fn source_pixel(
    params: &Params,
    layer: &Layer,
    window: &[i32],
    adjoint: &LayerAdjoint,
    own: &[[f64; 4]],
    leak: f64,
    x: i64,
    y: i64,
    reach: i64,
) -> ([f64; 4], f64, f64) {
    let width = params.width as i64;
    let iy = (y * width + x) as usize;
    let p = layer.rgba.pixels[iy];
    let src = Px::new(&params.lens, layer.disparity[iy], p[3]);
    let [own_alpha, own_s, own_rel, _] = own[iy];
    let mut d_p = [0.0, 0.0, 0.0, own_alpha];
    let (mut d_s, mut d_rel) = (own_s, own_rel);
    for (ox, oy, ix) in clipped_window(params, x, y, reach) {
        let (rx, ry) = ((x + ox) as usize, (y + oy) as usize);
        let h = window[(ry / TILE) * params.tiles_x + rx / TILE] as i64;
        if ox.abs() > h || oy.abs() > h {
            continue; // receiver (rx, ry)'s window does not hold this source
        }
        let dst = Px::new(&params.lens, layer.disparity[ix], layer.rgba.pixels[ix][3]);
        let (dx, dy) = (ox as f64, oy as f64);
        if p[3] > 0.0 {
            let [gc0, gc1, gc2, gw] = adjoint.cw[ix];
            let pg = pair_grad(params, leak, dx, dy, &src, &dst, ox == 0 && oy == 0);
            d_p = [d_p[0] + gc0 * pg.w, d_p[1] + gc1 * pg.w, d_p[2] + gc2 * pg.w, d_p[3] + gw * pg.w];
            let a = gc0 * p[0] as f64 + gc1 * p[1] as f64 + gc2 * p[2] as f64 + gw * src.alpha;
            d_s += a * pg.s_y;
            d_rel += a * pg.rel_y;
        }
        d_p[3] += own[ix][3] * vis_share(params, dx, dy, &dst);
    }
    (d_p, params.lens.k_px * d_s + d_rel, src.rel * d_s)
}

/// dV(x)/dalpha_y times `sum D` (the adjoint `own[3]` already holds `dL/dV / sum D`).
fn vis_share(params: &Params, dx: f64, dy: f64, dst: &Px) -> f64 {
    match params.model {
        Model::DrBokeh => vis_weight(params, 0.0, dx, dy, dst).0,
        Model::Compat => {
            let half = math::visibility_box_compat(dst.r) as f64;
            if dx.abs() <= half && dy.abs() <= half {
                1.0
            } else {
                0.0
            }
        }
    }
}
