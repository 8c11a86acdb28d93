//! f64 CPU reference of the Dr.Bokeh passes, shaped like the shaders: `layer_pixel` is the
//! body of `drbokeh_layer.comp`, `composite_pixel` the body of `drbokeh_composite.comp`, with
//! the same loops in the same order, so each pair can be diffed by eye.
use rayon::prelude::*;

use super::bounds::{grow_windows, tile_bounds_cpu, tile_window_cpu};
use super::{math, Model, Params, TILE};
use crate::image::Image;
use crate::render::Lens;
use crate::stack::{Layer, LayerStack};
use crate::Result;

/// Which source window each output pixel loops over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Window {
    /// The per-tile windows of the bounds passes (what the shaders do).
    Tiled,
    /// Every pixel of the image (the unwindowed sum, for tests).
    Full,
    /// The per-tile windows grown by this many pixels (non-empty tiles only): the leaky
    /// backward evaluates pairs just outside the supports, which add exact zeros forward.
    TiledGrown(i32),
}

/// Intermediates of one layer, per pixel: `cw = [C_l.rgb, W_l]` (the `layer_cw` buffer) and
/// `visibility = V_l` (the `layer_vis` buffer), plus the window half-width per tile.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerTerms {
    pub cw: Vec<[f64; 4]>,
    pub visibility: Vec<f64>,
    pub window: Vec<i32>,
}

/// Everything a render computes: per-layer terms, the f64 composite and the output image.
#[derive(Clone, Debug, PartialEq)]
pub struct Terms {
    pub params: Params,
    pub layers: Vec<LayerTerms>,
    pub composite: Vec<[f64; 4]>,
    pub image: Image,
}

/// Renders `stack` through `lens`: premultiplied linear RGBA, HDR unclamped, alpha = coverage.
pub fn render_cpu(stack: &LayerStack, lens: &Lens, model: Model) -> Result<Image> {
    Ok(render_cpu_terms(stack, lens, model, Window::Tiled)?.image)
}

/// [`render_cpu`] keeping every intermediate (for tests and the backward pass).
pub fn render_cpu_terms(stack: &LayerStack, lens: &Lens, model: Model, window: Window) -> Result<Terms> {
    Ok(render_cpu_params(stack, Params::new(stack, lens, model)?, window))
}

/// [`render_cpu_terms`] with prepared parameters (tests set the lens scalars in f64 through
/// `params.lens`, for finite differences finer than f32 can step).
pub fn render_cpu_params(stack: &LayerStack, params: Params, window: Window) -> Terms {
    let layers: Vec<LayerTerms> = stack
        .layers
        .iter()
        .map(|layer| {
            let windows = match window {
                Window::Tiled => tile_window_cpu(&params, &tile_bounds_cpu(&params, layer)),
                Window::TiledGrown(margin) => grow_windows(tile_window_cpu(&params, &tile_bounds_cpu(&params, layer)), margin),
                Window::Full => vec![params.width.max(params.height) as i32; params.tiles_x * params.tiles_y],
            };
            layer_cpu(&params, layer, windows)
        })
        .collect();
    let composite: Vec<[f64; 4]> =
        (0..params.width * params.height).map(|i| composite_pixel(&params, &layers, i)).collect();
    let mut image = Image::new(params.width, params.height);
    for (out, c) in image.pixels.iter_mut().zip(&composite) {
        *out = c.map(|v| v as f32);
    }
    Terms { params, layers, composite, image }
}

/// One dispatch of `drbokeh_layer.comp` on `layer`.
pub fn layer_cpu(params: &Params, layer: &Layer, window: Vec<i32>) -> LayerTerms {
    let n = params.width * params.height;
    let per_pixel: Vec<([f64; 4], f64)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i % params.width) as i64, (i / params.width) as i64);
            let tile = (y as usize / TILE) * params.tiles_x + x as usize / TILE;
            layer_pixel(params, layer, x, y, window[tile] as i64)
        })
        .collect();
    let (cw, visibility) = per_pixel.into_iter().unzip();
    LayerTerms { cw, visibility, window }
}

/// `[C.rgb, W]` and `V` of output pixel (x, y) over the square window of half-width `h`.
fn layer_pixel(params: &Params, layer: &Layer, x: i64, y: i64, h: i64) -> ([f64; 4], f64) {
    let width = params.width as i64;
    // A vignetted lens's shape is the receiver tile's.
    let lens = &*params.receiver_lens(x as usize, y as usize);
    let ix = (y * width + x) as usize;
    let rel_x = lens.rel(layer.disparity[ix]);
    let s_x = lens.k_px * rel_x;
    let r_x = s_x.abs();
    let alpha_x = layer.rgba.pixels[ix][3] as f64;
    let box_half = math::visibility_box_compat(r_x);

    let mut cw = [0.0f64; 4];
    let (mut vis_sum, mut vis_weight) = (0.0f64, 0.0f64);
    for (ox, oy, iy) in clipped_window(params, x, y, h) {
        let (sx, sy) = ((x + ox) as usize, (y + oy) as usize);
        let p = layer.rgba.pixels[iy];
        let alpha_y = p[3] as f64;
        let rel_y = lens.rel(layer.disparity[iy]);
        let s_y = lens.k_px * rel_y;
        let r_y = s_y.abs();
        // Offset x - y: the lens term is evaluated where the source lands.
        let (dx, dy) = (-ox as f64, -oy as f64);
        let is_self = ox == 0 && oy == 0;

        if alpha_y > 0.0 {
            let (g, k) = lens.lens(dx, dy, r_y, rel_y);
            let (s, o) = match params.model {
                Model::DrBokeh => (math::scatter(r_y, g), math::occlusion(s_y, s_x, r_x, alpha_x, is_self)),
                Model::Compat => (math::scatter_compat(r_y, g), math::occlusion_compat(rel_y, rel_x, r_x, is_self)),
            };
            let weight = s * k * o / params.area_at(r_y, sx, sy);
            for c in 0..3 {
                cw[c] += p[c] as f64 * weight;
            }
            cw[3] += alpha_y * weight;
        }

        match params.model {
            Model::DrBokeh => {
                let (g, k) = lens.lens(dx, dy, r_x, rel_x);
                let d = math::footprint(r_x, g) * k;
                vis_sum += alpha_y * d;
                vis_weight += d;
            }
            Model::Compat => {
                if ox.abs() <= box_half && oy.abs() <= box_half {
                    vis_sum += alpha_y;
                    vis_weight += 1.0;
                }
            }
        }
    }
    let visibility = if vis_weight > 0.0 { vis_sum / vis_weight } else { 0.0 };
    (cw, visibility)
}

/// The pixels of the square window of half-width `h` around `(x, y)` that lie in the image,
/// row by row, as `(ox, oy, index)`: the loop of every pass of the CPU reference, forward and
/// backward (the shaders clip their rows and columns the same way).
pub(super) fn clipped_window(params: &Params, x: i64, y: i64, h: i64) -> impl Iterator<Item = (i64, i64, usize)> {
    let (width, height) = (params.width as i64, params.height as i64);
    (-h..=h).filter(move |oy| (0..height).contains(&(y + oy))).flat_map(move |oy| {
        (-h..=h).filter(move |ox| (0..width).contains(&(x + ox))).map(move |ox| (ox, oy, ((y + oy) * width + x + ox) as usize))
    })
}

/// Body of `drbokeh_composite.comp` (`drbokeh_composite_step` per layer, which a forward render
/// layer by layer runs at the end of each layer pass): front-to-back blend of the layer
/// colours `C_l / W_l`.
fn composite_pixel(params: &Params, layers: &[LayerTerms], i: usize) -> [f64; 4] {
    let mut out = [0.0f64; 4];
    let mut transmittance = 1.0f64;
    for terms in layers {
        composite_step(params.model, terms.cw[i], terms.visibility[i], &mut out, &mut transmittance);
    }
    out
}

/// One layer of the front-to-back composite (`drbokeh_composite_step`): the layer's colour
/// `C_l / W_l` (`cw = [C_l.rgb, W_l]`) at visibility `V_l`, gated by existence under the default
/// model, added to `out` through `transmittance`, which the layer then reduces. Shared by the
/// reference and the fast CPU path (`native.rs`), so both blend with the same arithmetic.
#[inline]
pub(super) fn composite_step(model: Model, cw: [f64; 4], visibility: f64, out: &mut [f64; 4], transmittance: &mut f64) {
    let [c0, c1, c2, w] = cw;
    let mut v = visibility;
    if model == Model::DrBokeh {
        v *= math::existence_gate(w);
    }
    let colour = if w > 0.0 { [c0 / w, c1 / w, c2 / w] } else { [0.0; 3] };
    for c in 0..3 {
        out[c] += *transmittance * v * colour[c];
    }
    out[3] += *transmittance * v;
    *transmittance *= 1.0 - v;
}
