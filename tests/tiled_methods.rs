//! Every Vulkan method on frame tiles (`src/render/tiling.rs`): the output is bit-identical for
//! every tile size — odd sides, sides that do not divide the frame, one whole-frame tile — and
//! a tiled render equals the method's CPU reference within the tolerance its own test states.
mod common;

use std::sync::atomic::{AtomicUsize, Ordering};

use common::{finish, gpu, max_abs_diff, pattern};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::RenderOptions;
use lensblur::render::gather::render_gather_cpu;
use lensblur::render::multiview::{render_multiview_cpu, Multiview, MultiviewParams};
use lensblur::render::scatter::render_scatter_cpu;
use lensblur::render::vdslr::{render_vdslr_cpu, FocusField};
use lensblur::render::{Lens, Method, MethodSettings};
use lensblur::stack::{Layer, LayerStack};
use lensblur::vk::Context;

const WIDTH: usize = 45;
const HEIGHT: usize = 37;
/// Tile sides: odd, not dividing the frame, Dr.Bokeh's alignment, and past the frame (one tile).
const TILES: [usize; 5] = [5, 13, 16, 31, 64];

/// A near square over a far textured layer with a slanted depth: CoC radii of both signs up to
/// about 10 px, so halos are several tiles wide at the small sides.
fn stack() -> LayerStack {
    stack_sized(WIDTH, HEIGHT)
}

/// [`stack`] on a `w x h` frame.
fn stack_sized(w: usize, h: usize) -> LayerStack {
    let near = Image::from_fn(w, h, |x, y| {
        if (8..22).contains(&x) && (6..20).contains(&y) {
            [2.0, 0.3, 0.1, 1.0]
        } else {
            [0.0; 4]
        }
    });
    let far = Image::from_fn(w, h, |x, y| {
        let p = pattern(w, h).get(x, y);
        [p[0], p[1], p[2], 1.0]
    });
    let layers = vec![
        Layer { name: "near".into(), rgba: near, disparity: vec![0.9; w * h] },
        Layer {
            name: "far".into(),
            rgba: far,
            disparity: (0..w * h).map(|i| 0.1 + 0.3 * (i % w) as f32 / w as f32).collect(),
        },
    ];
    LayerStack::new(w, h, layers).unwrap()
}

fn lens(aperture: Aperture) -> Lens {
    Lens { coc: CocModel::new(14.0, 0.5).unwrap(), aperture }
}

/// Few samples keep lavapipe fast; a tilted focal plane makes Virtual DSLR's relative
/// disparity depend on the position relative to the frame centre.
fn settings() -> MethodSettings {
    let mut settings = MethodSettings::default();
    (settings.vdslr.samples, settings.multiview.samples) = (24, 24);
    settings.vdslr.focus = FocusField::Tilt { gradient: [0.004, -0.006] };
    settings
}

fn bits(image: &Image) -> Vec<u32> {
    image.pixels.iter().flatten().map(|v| v.to_bits()).collect()
}

/// Renders through the registry (as `lensblur render` does) on `tile`-sided tiles; returns the
/// image and the tile count the progress hook reported.
fn render(ctx: &Context, method: Method, lens: &Lens, tile: usize) -> (Image, usize) {
    let total = AtomicUsize::new(0);
    let progress = |_: usize, all: usize| total.store(all, Ordering::Relaxed);
    let options = RenderOptions { tile: Some(tile), progress: Some(&progress), ..RenderOptions::default() };
    let image = method
        .render_with(Some(ctx), &stack(), lens, &options, &settings())
        .unwrap_or_else(|e| panic!("{method}: {e}"));
    (image, total.load(Ordering::Relaxed))
}

#[test]
fn every_vulkan_method_is_bit_identical_whatever_the_tile_size() {
    let ctx = gpu();
    for aperture in [Aperture::Disk, Aperture::polygon(5, 10.0, 0.0).unwrap()] {
        let lens = lens(aperture);
        for &method in Method::ALL.iter().filter(|m| m.uses_gpu()) {
            let (whole, tiles) = render(&ctx, method, &lens, 64);
            assert_eq!(tiles, 1, "{method}: a tile past the frame is the whole frame");
            for tile in TILES {
                let (image, tiles) = render(&ctx, method, &lens, tile);
                // Dr.Bokeh's tiles are whole 16x16 search tiles: its sides round up to 16.
                let side = if method.name().starts_with("drbokeh") { tile.div_ceil(16) * 16 } else { tile };
                assert_eq!(tiles, WIDTH.div_ceil(side) * HEIGHT.div_ceil(side), "{method} tile {tile}: tile count");
                assert!(
                    bits(&image) == bits(&whole),
                    "{method} tile {tile}: differs from the whole frame by {}",
                    max_abs_diff(&image, &whole)
                );
            }
        }
    }
    finish(ctx);
}

/// The tiled renders against the CPU references, with the tolerances of tests/baselines_gpu.rs,
/// tests/vdslr.rs and tests/multiview.rs (same taps; ulps of tanh, atan, exp, FMA contraction).
#[test]
fn tiled_renders_match_the_cpu_references() {
    let ctx = gpu();
    let (stack, lens, settings) = (stack(), lens(Aperture::Disk), settings());
    let (image, disparity) = stack.flatten();
    let scale = image.pixels.iter().flatten().fold(1.0f32, |m, v| m.max(v.abs()));
    let tiled = |method: Method| render(&ctx, method, &lens, 13).0;
    let gather = max_abs_diff(&tiled(Method::Gather), &render_gather_cpu(&image, &disparity, &lens)) / scale;
    assert!(gather <= 1e-5, "gather: relative max |gpu - cpu| = {gather}");
    let scatter = max_abs_diff(&tiled(Method::Scatter), &render_scatter_cpu(&image, &disparity, &lens)) / scale;
    assert!(scatter <= 1e-5, "scatter: relative max |gpu - cpu| = {scatter}");
    let vdslr =
        max_abs_diff(&tiled(Method::Vdslr), &render_vdslr_cpu(&image, &disparity, &lens, &settings.vdslr).unwrap());
    assert!(vdslr <= 2e-4, "vdslr: max |gpu - cpu| = {vdslr}");
    let multiview =
        max_abs_diff(&tiled(Method::Multiview), &render_multiview_cpu(&stack, &lens, &settings.multiview).unwrap());
    assert!(multiview <= 2e-4, "multiview: max |gpu - cpu| = {multiview}");
    finish(ctx);
}

/// Multiview's tiles read windows of the layers aligned to the top mip level their cones read.
/// Wider cones (top levels 4 and 5: windows aligned to 16 and 32 px, cut at the frame's edges)
/// on a frame several windows wide still give every tile the whole frame's bytes, which match
/// the CPU reference, while a tile holds less than the whole frame's inputs.
#[test]
fn multiview_windows_aligned_to_coarse_levels_keep_the_bytes() {
    let ctx = gpu();
    let mv = Multiview::new(&ctx).unwrap();
    let (stack, lens) = (stack_sized(150, 100), lens(Aperture::Disk));
    for cone_scale in [2.0, 4.0] {
        let params = MultiviewParams { samples: 16, cone_scale, ..Default::default() };
        let run = |tile: usize| {
            let options = RenderOptions { tile: Some(tile), tiles_per_batch: Some(1), ..RenderOptions::default() };
            mv.run_with(&stack, &lens, &params, &options).unwrap()
        };
        let (whole, whole_stats) = run(256);
        for tile in [13, 31, 64] {
            let (image, stats) = run(tile);
            assert!(
                bits(&image) == bits(&whole),
                "cone scale {cone_scale}, tile {tile}: differs from the whole frame by {}",
                max_abs_diff(&image, &whole)
            );
            assert!(stats.peak_device_bytes < whole_stats.peak_device_bytes, "tile {tile}: {stats:?} {whole_stats:?}");
        }
        let cpu = render_multiview_cpu(&stack, &lens, &params).unwrap();
        let diff = max_abs_diff(&whole, &cpu);
        assert!(diff <= 2e-4, "cone scale {cone_scale}: max |gpu - cpu| = {diff}");
    }
    drop(mv);
    finish(ctx);
}

/// The service's out-of-memory retry serves every method: a frame refused at its first tile
/// size comes out of smaller tiles, identical.
#[test]
fn out_of_device_memory_retries_smaller_tiles_for_a_non_drbokeh_method() {
    let ctx = gpu();
    let mv = Multiview::new(&ctx).unwrap();
    let (stack, lens) = (stack(), lens(Aperture::Disk));
    let params = MultiviewParams { samples: 16, ..Default::default() };
    // A memory cap of 1 GiB plans the small frame as one tile.
    let roomy = RenderOptions { max_memory: Some(1 << 30), ..RenderOptions::default() };
    let (whole, stats) = mv.run_with(&stack, &lens, &params, &roomy).unwrap();
    assert_eq!(stats.tiles, 1, "the small frame fits as one tile");
    // A tile holds its window's inputs and its core's result: a limit between what one 16 px
    // tile and the whole frame hold refuses the whole frame and admits 16 px tiles one by one.
    let one_by_one = RenderOptions { tile: Some(16), tiles_per_batch: Some(1), ..roomy };
    let small = mv.run_with(&stack, &lens, &params, &one_by_one).unwrap().1.peak_device_bytes;
    assert!(small < stats.peak_device_bytes, "a 16 px tile holds less than the whole frame: {small} vs {stats:?}");
    let limit = (small + stats.peak_device_bytes) / 2;
    let limited = RenderOptions { device_memory_limit: Some(limit), tiles_per_batch: Some(1), ..roomy };
    let (image, stats) = mv.run_with(&stack, &lens, &params, &limited).unwrap();
    assert!(stats.tiles > 1 && stats.tile_size < WIDTH, "{stats:?}");
    assert!(bits(&image) == bits(&whole), "retry changed the output by {}", max_abs_diff(&image, &whole));
    drop(mv);
    finish(ctx);
}
