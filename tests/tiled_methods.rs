//! Every Vulkan method on frame tiles (`src/render/tiler.rs`): the output is bit-identical for
//! every tile size — odd sides, sides that do not divide the frame, one whole-frame tile — and
//! a tiled render equals the method's CPU reference within the tolerance its own test states.
mod common;

use std::sync::atomic::{AtomicUsize, Ordering};

use common::{finish, gpu, max_abs_diff, pattern};
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::RenderOptions;
use lensblur::render::multiview::{render_multiview_cpu, Multiview, MultiviewParams};
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
    lensblur_dev::selfcheck::scenes::few_samples()
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

/// A discrete GPU's device memory is not host-visible: inputs go up through staging memory and
/// copies (the batch's arena, reused across submissions) and results come back the same way.
/// Forced here on a device whose memory is mappable, every method's tiled render and the
/// backward pass, over several submissions, equal the direct path bit for bit, with
/// synchronization validation on.
#[test]
fn staged_transfers_give_the_bytes_of_direct_ones() {
    let direct = gpu();
    let options = lensblur::vk::ContextOptions {
        validation: true,
        staged_transfers: true,
        ..lensblur::vk::ContextOptions::from_env()
    };
    let staged =
        Context::new(&options).unwrap_or_else(|e| panic!("GPU tests need a Vulkan device with validation layers: {e}"));
    let lens = lens(Aperture::polygon(5, 10.0, 0.0).unwrap());
    let one_per_batch = |tile| RenderOptions { tile: Some(tile), tiles_per_batch: Some(1), ..RenderOptions::default() };
    for &method in Method::ALL.iter().filter(|m| m.uses_gpu()) {
        let tile = if method.name().starts_with("drbokeh") { 16 } else { 13 };
        let run =
            |ctx: &Context| method.render_with(Some(ctx), &stack(), &lens, &one_per_batch(tile), &settings()).unwrap();
        let (a, b) = (run(&direct), run(&staged));
        assert!(bits(&a) == bits(&b), "{method}: staged transfers change the render by {}", max_abs_diff(&a, &b));
    }
    let grad_output = lensblur_dev::selfcheck::scenes::grad_output(WIDTH, HEIGHT);
    let gradients = |ctx: &Context| {
        let renderer = lensblur::render::drbokeh::DrBokehGpuGrad::new(
            ctx,
            lensblur::render::drbokeh::Model::DrBokeh,
            lensblur::render::drbokeh::BackwardOptions::exact(),
        )
        .unwrap();
        let (g, _) = renderer.backward_with(&stack(), &lens, &grad_output, &one_per_batch(16)).unwrap();
        g.layers
            .iter()
            .flat_map(|l| l.rgba.iter().flatten().chain(&l.disparity).map(|v| v.to_bits()).collect::<Vec<_>>())
            .collect::<Vec<u32>>()
    };
    assert!(gradients(&direct) == gradients(&staged), "staged transfers change the gradients");
    finish(staged);
    finish(direct);
}

/// Where a GPU's watchdog bound cuts the frame (simulated here with the testing aid), the first
/// batch measures the device and the rest of the frame gets tiles as large as that speed allows:
/// fewer, larger tiles than the bound's grid, and the same bytes.
#[test]
fn tiles_grow_after_the_first_batch_measures_the_device() {
    let ctx = gpu();
    let (stack, lens) = (stack_sized(150, 100), lens(Aperture::Disk));
    for &method in Method::ALL.iter().filter(|m| m.uses_gpu()) {
        let whole = method.render_with(Some(&ctx), &stack, &lens, &RenderOptions::default(), &settings()).unwrap();
        // A bound a few hundred pixels' work wide. With every tile in one batch nothing is left
        // to grow into: that render counts the bound's own grid.
        let render = |tiles_per_batch: usize| {
            let total = AtomicUsize::new(0);
            let progress = |_: usize, all: usize| total.store(all, Ordering::Relaxed);
            let options = RenderOptions {
                max_tile_work: Some(50_000),
                tiles_per_batch: Some(tiles_per_batch),
                progress: Some(&progress),
                ..RenderOptions::default()
            };
            let image = method.render_with(Some(&ctx), &stack, &lens, &options, &settings()).unwrap();
            (image, total.load(Ordering::Relaxed))
        };
        let (grid, grid_tiles) = render(usize::MAX);
        let (grown, grown_tiles) = render(2);
        assert!(grid_tiles > 4, "{method}: the bound cuts the frame ({grid_tiles} tiles)");
        assert!(
            grown_tiles < grid_tiles,
            "{method}: {grown_tiles} tiles after growth, {grid_tiles} in the bound's grid"
        );
        for (label, image) in [("the bound's grid", &grid), ("grown tiles", &grown)] {
            assert!(
                bits(image) == bits(&whole),
                "{method}: {label} change the render by {}",
                max_abs_diff(image, &whole)
            );
        }
    }
    finish(ctx);
}

// Tiled and untiled renders of every method against its CPU reference are self-checks
// (dev/src/selfcheck, run by tests/gpu_kit.rs and by the GPU kit on real GPUs).

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
