//! Debug views a compositor sets focus with (`--debug-out DIR`): signed CoC map, layer
//! assignment, focus peaking over the render, and per-layer visibility V_l of Dr.Bokeh.
use std::path::{Path, PathBuf};

use crate::image::Image;
use crate::render::drbokeh::{render_cpu_terms, Model, Window};
use crate::camera::FocusField;
use crate::render::Lens;
use crate::stack::{write_png_preview, LayerStack};
use crate::tile_grid::Rect;
use crate::Result;
use super::vignette::crop;

/// Sobel gradient of display luminance (per pixel) above which a pixel is "in focus": a sharp
/// 0-1 step gives 0.5, the same step blurred over 8 px about 0.06.
pub const PEAKING_THRESHOLD: f32 = 0.2;
/// Largest side of the copy the CPU visibility reference runs on (it is O(pixels * CoC^2)).
pub const VISIBILITY_MAX_SIDE: usize = 128;

const WARM: [f32; 3] = [1.0, 0.35, 0.05];
const COOL: [f32; 3] = [0.05, 0.3, 1.0];
const PEAK: [f32; 3] = [0.0, 1.0, 0.1];
const PALETTE: [[f32; 3]; 8] = [
    [0.9, 0.1, 0.1], [0.1, 0.7, 0.1], [0.1, 0.2, 0.9], [0.9, 0.8, 0.1],
    [0.8, 0.1, 0.8], [0.1, 0.8, 0.8], [0.9, 0.5, 0.1], [0.6, 0.6, 0.6],
];

/// Signed CoC per pixel (flattened disparity; positive = nearer than focus), relative to the
/// focus field rendered (a tilted plane or several planes for Virtual DSLR).
pub fn coc_map(stack: &LayerStack, lens: &Lens, focus: &FocusField) -> Result<Vec<f32>> {
    let relative = focus.relative_disparity(&stack.flatten().1, stack.width, stack.height, &lens.coc)?;
    Ok(relative.iter().map(|&r| lens.coc.k_px * r).collect())
}

/// The CoC map coloured: near warm, far cool, brightness sqrt(|r| / largest |r|), focus black.
pub fn coc_image(width: usize, height: usize, coc: &[f32]) -> Image {
    let largest = coc.iter().fold(0.0f32, |m, r| m.max(r.abs())).max(1e-6);
    Image::from_fn(width, height, |x, y| {
        let r = coc[y * width + x];
        let t = (r.abs() / largest).sqrt();
        let hue = if r > 0.0 { WARM } else { COOL };
        [hue[0] * t, hue[1] * t, hue[2] * t, 1.0]
    })
}

/// Index of the layer a pixel shows: front-most with alpha >= 0.5, else front-most with any
/// coverage, else `None` (empty).
pub fn layer_assignment(stack: &LayerStack) -> Vec<Option<usize>> {
    (0..stack.width * stack.height)
        .map(|i| {
            let alpha = |l: &crate::stack::Layer| l.rgba.pixels[i][3];
            let layers = &stack.layers;
            layers.iter().position(|l| alpha(l) >= 0.5).or_else(|| layers.iter().position(|l| alpha(l) > 0.0))
        })
        .collect()
}

/// Pixels of `image` whose display luminance has a Sobel gradient above [`PEAKING_THRESHOLD`].
pub fn focus_peaking(image: &Image) -> Vec<bool> {
    let luma = |x: i64, y: i64| {
        let p = image.get_clamped(x, y);
        let a = p[3].max(1e-6);
        let l = (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) / a;
        crate::stack::ldr::linear_to_srgb(l.clamp(0.0, 1.0))
    };
    (0..image.width * image.height)
        .map(|i| {
            let (x, y) = ((i % image.width) as i64, (i / image.width) as i64);
            let col = |dx: i64| luma(x + dx, y - 1) + 2.0 * luma(x + dx, y) + luma(x + dx, y + 1);
            let row = |dy: i64| luma(x - 1, y + dy) + 2.0 * luma(x, y + dy) + luma(x + 1, y + dy);
            // Sobel sums 4 central differences over 2 px: / 8 gives the gradient per pixel.
            let (gx, gy) = ((col(1) - col(-1)) / 8.0, (row(1) - row(-1)) / 8.0);
            (gx * gx + gy * gy).sqrt() > PEAKING_THRESHOLD
        })
        .collect()
}

/// Writes every debug view into `dir` (created if missing); returns the files written.
/// `stack`, `lens` and `focus` are what was rendered (after any remap, focus pick or bloom).
///
/// The stack and render hold the frame `frame_margin` pixels inside their edge (a canvas
/// guessed beyond the frame: [`crate::input::LoadedInput::frame_margin`]): the views show the
/// frame, as the output does.
pub fn write_debug_views(
    dir: &Path,
    stack: &LayerStack,
    lens: &Lens,
    focus: &FocusField,
    rendered: &Image,
    frame_margin: usize,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| crate::Error::input(dir, format!("cannot create the debug folder: {e}")))?;
    let framed;
    let (stack, rendered) = if frame_margin > 0 {
        let (x1, y1) = (stack.width - frame_margin, stack.height - frame_margin);
        let frame = Rect { x0: frame_margin, y0: frame_margin, x1, y1 };
        framed = (crop(stack, frame)?, rendered.without_border(frame_margin).expect("the canvas holds the frame"));
        (&framed.0, &framed.1)
    } else {
        (stack, rendered)
    };
    let (w, h) = (stack.width, stack.height);
    let mut written = Vec::new();
    let mut save = |name: String, image: &Image| -> Result<()> {
        let path = dir.join(name);
        write_png_preview(&path, image)?;
        written.push(path);
        Ok(())
    };
    save(COC_VIEW.into(), &coc_image(w, h, &coc_map(stack, lens, focus)?))?;
    save(LAYERS_VIEW.into(), &layers_image(stack))?;
    save(PEAKING_VIEW.into(), &peaking_overlay(rendered))?;
    for (l, v) in visibility(stack, lens)?.iter().enumerate() {
        save(visibility_view(l, &stack.layers[l].name), v)?;
    }
    Ok(written)
}

const COC_VIEW: &str = "coc.png";
const LAYERS_VIEW: &str = "layers.png";
const PEAKING_VIEW: &str = "focus_peaking.png";

fn visibility_view(layer_index: usize, layer_name: &str) -> String {
    format!("visibility_{layer_index}_{}.png", sanitise(layer_name))
}

/// The file names [`write_debug_views`] writes for `stack`. The CLI checks them against its
/// inputs and outputs before rendering.
pub fn debug_view_names(stack: &LayerStack) -> Vec<String> {
    let fixed = [COC_VIEW, LAYERS_VIEW, PEAKING_VIEW].map(String::from);
    fixed.into_iter().chain(stack.layers.iter().enumerate().map(|(l, layer)| visibility_view(l, &layer.name))).collect()
}

/// The layer assignment, one palette colour per layer (black: empty).
pub fn layers_image(stack: &LayerStack) -> Image {
    let (w, layers) = (stack.width, layer_assignment(stack));
    Image::from_fn(w, stack.height, |x, y| match layers[y * w + x] {
        Some(l) => { let c = PALETTE[l % PALETTE.len()]; [c[0], c[1], c[2], 1.0] }
        None => [0.0, 0.0, 0.0, 1.0],
    })
}

/// The render darkened to grey, with peaking pixels marked.
pub fn peaking_overlay(rendered: &Image) -> Image {
    let peaks = focus_peaking(rendered);
    let mut out = Image::from_fn(rendered.width, rendered.height, |x, y| {
        let p = rendered.get(x, y);
        let l = 0.5 * (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) / p[3].max(1e-6);
        [l, l, l, 1.0]
    });
    for (o, _) in out.pixels.iter_mut().zip(&peaks).filter(|(_, &peak)| peak) {
        *o = [PEAK[0], PEAK[1], PEAK[2], 1.0];
    }
    out
}

/// V_l of every layer (grey images), from the CPU reference on a copy downscaled to at most
/// [`VISIBILITY_MAX_SIDE`] (K scaled with it), upscaled back by nearest neighbour.
pub fn visibility(stack: &LayerStack, lens: &Lens) -> Result<Vec<Image>> {
    let factor = stack.width.max(stack.height).div_ceil(VISIBILITY_MAX_SIDE).max(1);
    let small = downscale(stack, factor)?;
    let mut small_lens = lens.clone();
    small_lens.coc.k_px /= factor as f32;
    let terms = render_cpu_terms(&small, &small_lens, Model::DrBokeh, Window::Tiled)?;
    Ok(terms
        .layers
        .iter()
        .map(|t| {
            Image::from_fn(stack.width, stack.height, |x, y| {
                let i = (y / factor).min(small.height - 1) * small.width + (x / factor).min(small.width - 1);
                let v = t.visibility[i] as f32;
                [v, v, v, 1.0]
            })
        })
        .collect())
}

/// Box-filtered colour, disparity sampled at each block's centre (depth must not be averaged
/// across an edge).
fn downscale(stack: &LayerStack, factor: usize) -> Result<LayerStack> {
    if factor == 1 {
        return Ok(stack.clone());
    }
    let (w, h) = (stack.width.div_ceil(factor), stack.height.div_ceil(factor));
    let layers = stack.layers.iter().map(|layer| {
        let rgba = Image::from_fn(w, h, |x, y| {
            let (mut sum, mut n) = ([0.0f32; 4], 0.0f32);
            for sy in y * factor..((y + 1) * factor).min(stack.height) {
                for sx in x * factor..((x + 1) * factor).min(stack.width) {
                    let p = layer.rgba.get(sx, sy);
                    (0..4).for_each(|c| sum[c] += p[c]);
                    n += 1.0;
                }
            }
            sum.map(|v| v / n)
        });
        let centre = |x: usize, y: usize| {
            let (cx, cy) = ((x * factor + factor / 2).min(stack.width - 1), (y * factor + factor / 2).min(stack.height - 1));
            layer.disparity[cy * stack.width + cx]
        };
        let disparity = (0..w * h).map(|i| centre(i % w, i / w)).collect();
        crate::stack::Layer { name: layer.name.clone(), rgba, disparity }
    });
    LayerStack::new(w, h, layers.collect())
}

fn sanitise(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}
