//! The Dr.Bokeh shaders: the optimised kernel against the baseline and further properties. The
//! comparison of every aperture path with the f64 CPU reference is in the self-check
//! (dev/src/selfcheck, run by tests/gpu_kit.rs).
mod common;

use common::{finish, gpu};
use lensblur::camera::{Aperture, CocModel, KernelImage};
use lensblur::render::drbokeh::{render_cpu, DrBokehGpu, LayerKernel, Model};
use lensblur::render::Lens;
use lensblur::stack::LayerStack;

use lensblur_dev::selfcheck::scenes::forward as scene;

// Largest difference relative to max(1, |cpu|) (HDR highlights reach ~40): the self-check's
// metric.
use lensblur_dev::selfcheck::image_difference as worst_relative;

// Every aperture path of both models against the CPU reference, untiled and tiled, is a
// self-check (dev/src/selfcheck, run by tests/gpu_kit.rs and by the GPU kit on real GPUs).

#[test]
fn optimised_kernel_matches_the_baseline_kernel_for_both_models_and_every_aperture() {
    let ctx = gpu();
    let optimised = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let baseline = DrBokehGpu::with_kernel(&ctx, LayerKernel::Baseline).unwrap();
    // 50x40 with K = 25: windows of ~13 px, so the window disk and the border clipping both cut;
    // 50 is not a multiple of the 8-pixel runs.
    let stack = scene(50, 40);
    let kernel = KernelImage::from_weights(2, vec![1.0, 0.5, 0.5, 1.0]).unwrap();
    let apertures = [
        Aperture::Disk,
        Aperture::polygon(5, 10.0, 0.0).unwrap(),
        Aperture::ring(0.4).unwrap(),
        Aperture::Kernel(kernel),
    ];
    for model in [Model::DrBokeh, Model::Compat] {
        for aperture in &apertures {
            let lens = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: aperture.clone() };
            let fast = optimised.render(&stack, &lens, model).unwrap();
            let first = baseline.render(&stack, &lens, model).unwrap();
            if model == Model::DrBokeh {
                // The span paths (disk, polygon, ring, kernel) divide by the area once per source instead of
                // once per tap and sum interiors from block sums: f32 rounding only, each
                // kernel is within 5e-5 of the f64 reference.
                let worst = worst_relative(&fast, &first);
                assert!(worst < 5e-5, "{model:?} {aperture:?}: worst relative difference {worst}");
            } else {
                // Elsewhere only taps whose terms are exactly zero are skipped: same sums.
                let differing = fast.pixels.iter().zip(&first.pixels).filter(|(a, b)| a != b).count();
                assert_eq!(differing, 0, "{model:?} {aperture:?}: {differing} pixels differ from the baseline kernel");
            }
        }
    }
    drop((optimised, baseline));
    finish(ctx);
}

#[test]
fn gpu_render_is_deterministic() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = scene(40, 33);
    let lens = Lens { coc: CocModel::new(20.0, 0.5).unwrap(), aperture: Aperture::Disk };
    let first = renderer.render(&stack, &lens, Model::DrBokeh).unwrap();
    let second = renderer.render(&stack, &lens, Model::DrBokeh).unwrap();
    assert_eq!(first, second, "bit-identical across runs");
    drop(renderer);
    finish(ctx);
}

#[test]
fn output_is_bit_identical_whatever_the_tile_size_and_batch_size() {
    use lensblur::render::drbokeh::RenderOptions;
    use std::sync::Mutex;
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    // 83x61 is divisible by none of the tile sizes; K = 25 gives halos of ~13 px, wider than
    // the 16 px tiles, so tiles read well into their neighbours. Batches of 1, 5 (which divides
    // neither 24 nor 6 tiles) and as many as the budget allows (8 at most) share submissions.
    let stack = scene(83, 61);
    for model in [Model::DrBokeh, Model::Compat] {
        let lens = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: Aperture::polygon(5, 10.0, 0.0).unwrap() };
        let (whole, stats) = renderer.render_with(&stack, &lens, model, &RenderOptions::default()).unwrap();
        assert_eq!((stats.tiles, stats.tiles_per_batch), (1, 1), "a small frame is one tile");
        for tile in [16, 32, 40, 64] {
            for tiles_per_batch in [Some(1), Some(5), None] {
                let calls = Mutex::new(Vec::new());
                let progress = |finished: usize, total: usize| calls.lock().unwrap().push((finished, total));
                let options = RenderOptions {
                    tile: Some(tile),
                    tiles_per_batch,
                    progress: Some(&progress),
                    ..RenderOptions::default()
                };
                let (tiled, stats) = renderer.render_with(&stack, &lens, model, &options).unwrap();
                let label = format!("{model:?}, tile {tile}, {tiles_per_batch:?} per batch");
                let side = tile.div_ceil(16) * 16;
                assert_eq!(stats.tiles, 83usize.div_ceil(side) * 61usize.div_ceil(side), "{label}");
                if let Some(n) = tiles_per_batch {
                    assert_eq!(stats.tiles_per_batch, n.min(stats.tiles), "{label}");
                }
                let expected: Vec<(usize, usize)> = (1..=stats.tiles).map(|done| (done, stats.tiles)).collect();
                assert_eq!(*calls.lock().unwrap(), expected, "{label}: progress once per tile, in order");
                let differing = tiled.pixels.iter().zip(&whole.pixels).filter(|(a, b)| a != b).count();
                assert_eq!(differing, 0, "{label}: {differing} pixels differ from the untiled render");
            }
        }
    }
    drop(renderer);
    finish(ctx);
}

/// The device's buffer pool: a frame's tiles take the memory earlier tiles gave back, and a
/// later render of the frame takes all of its buffers from the pool. 160x160 in 32 px tiles, one
/// per batch: 25 tiles, whose buffers (sized for the largest tile, so that tiles the border
/// clips ask for the same sizes) come from those of the first. Tolerance: a first render makes
/// at most 2 tiles' buffers (the first tile's, and a second set only while a tile's read-back is
/// still held), at least 11 per tile; a second render makes none, nor does a render of one tile
/// per submission after one of several.
#[test]
fn tiles_and_renders_take_their_buffers_from_the_pool() {
    use lensblur::render::drbokeh::RenderOptions;
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = scene(160, 160);
    let lens = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: Aperture::Disk };
    let options = |tiles_per_batch| RenderOptions { tile: Some(32), tiles_per_batch, ..RenderOptions::default() };
    let render = |tiles_per_batch| {
        let before = ctx.buffer_pool_counts();
        let (image, stats) = renderer.render_with(&stack, &lens, Model::DrBokeh, &options(tiles_per_batch)).unwrap();
        let after = ctx.buffer_pool_counts();
        (image, stats, after.created - before.created, after.reused - before.reused)
    };
    let (first, stats, created, reused) = render(Some(1));
    assert_eq!(stats.tiles, 25);
    let requests = created + reused;
    assert!(requests >= 25 * 11, "{requests} buffer requests for 25 tiles");
    assert!(created <= 2 * requests / 25 + 4, "the first render made {created} of its {requests} buffers");
    let (second, _, created, reused) = render(Some(1));
    assert_eq!((created, reused), (0, requests), "the second render's buffers all come from the pool");
    assert!(first == second);
    let (batched, stats, created_batched, _) = render(None);
    assert!(stats.tiles_per_batch > 1 && batched == first, "{stats:?}");
    let (_, _, created, _) = render(Some(1));
    assert_eq!(created, 0, "after {created_batched} made for batches of several tiles, one per batch makes none");
    drop(renderer);
    finish(ctx);
}

#[test]
fn out_of_device_memory_retries_with_smaller_tiles_and_the_same_output() {
    use lensblur::render::drbokeh::RenderOptions;
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = scene(83, 61);
    let lens = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: Aperture::Disk };
    let (whole, whole_stats) = renderer.render_with(&stack, &lens, Model::DrBokeh, &RenderOptions::default()).unwrap();
    // Half of what the one-tile frame holds: the first attempt runs out of device memory and
    // the retries must shrink the tiles (and batches) until a batch fits.
    let limit = whole_stats.peak_device_bytes / 2;
    let options = RenderOptions { device_memory_limit: Some(limit), ..RenderOptions::default() };
    let (retried, stats) = renderer.render_with(&stack, &lens, Model::DrBokeh, &options).unwrap();
    assert!(stats.tile_size < whole_stats.tile_size && stats.tiles > 1, "{stats:?}");
    assert!(stats.peak_device_bytes <= limit, "{} bytes held, limit {limit}", stats.peak_device_bytes);
    let differing = retried.pixels.iter().zip(&whole.pixels).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "{differing} pixels of the retried render differ from the untiled one");
    // Not even one 16 px tile fits: a clear error, not a loop or a panic.
    let options = RenderOptions { device_memory_limit: Some(1), ..RenderOptions::default() };
    let error = renderer.render_with(&stack, &lens, Model::DrBokeh, &options).unwrap_err();
    let message = error.to_string();
    assert!(matches!(error, lensblur::Error::OutOfDeviceMemory { tile: 16, .. }), "{message}");
    for needle in ["out of device memory", "16 px tiles", "LENSBLUR_DEVICE", "--device cpu"] {
        assert!(message.contains(needle), "'{needle}' missing: {message}");
    }
    drop(renderer);
    finish(ctx);
}

/// A span path (`fast`) against a renderer that evaluates every tap (`reference`): within f32
/// rounding of the peak, and bit-identical for tiles that divide neither side.
fn assert_span_path_matches(fast: &DrBokehGpu, reference: &DrBokehGpu, stack: &LayerStack, lens: &Lens) {
    use lensblur::render::drbokeh::RenderOptions;
    let expected = reference.render(stack, lens, Model::DrBokeh).unwrap();
    let image = fast.render(stack, lens, Model::DrBokeh).unwrap();
    // Block sums add the same terms in another order: ~2000 f32 adds per pixel and layer
    // round to ~sqrt(n) 2^-24 ~ 3e-6 of the peak (4.8e-6 measured for the disk), while one
    // dropped or doubled tap of the ~20 px shapes moves a pixel by ~1 / (pi 20^2) ~ 8e-4 of
    // its value.
    let peak = expected.pixels.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
    let pairs = image.pixels.iter().flatten().zip(expected.pixels.iter().flatten());
    let worst = pairs.fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst <= 5e-5 * peak, "{:?}: span sums differ from every tap by {worst} (peak {peak})", lens.aperture);
    // Blocks are aligned to global columns: tiles of 32 and 48 px (neither divides 70 or 53)
    // cut spans elsewhere yet must sum the same values in the same order.
    for tile in [32, 48] {
        let options = RenderOptions { tile: Some(tile), ..RenderOptions::default() };
        let (tiled, _) = fast.render_with(stack, lens, Model::DrBokeh, &options).unwrap();
        let differing = tiled.pixels.iter().zip(&image.pixels).filter(|(a, b)| a != b).count();
        assert_eq!(differing, 0, "{:?} tile {tile}: {differing} pixels differ from the untiled render", lens.aperture);
    }
}

#[test]
fn disk_path_interior_matches_full_taps_and_is_bit_identical_tiled_or_not() {
    let ctx = gpu();
    let interior = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let full = DrBokehGpu::with_kernel(&ctx, LayerKernel::OptimisedNoInterior).unwrap();
    // K = 50 around focus 0.5: the tilted near layer (soft alpha edges) has CoC 20-25 px, the
    // HDR far one ~20 px, the ring is in focus (occluding centres); 70x53 divides no tile.
    let stack = scene(70, 53);
    let lens = Lens { coc: CocModel::new(50.0, 0.5).unwrap(), aperture: Aperture::Disk };
    assert_span_path_matches(&interior, &full, &stack, &lens);
    drop((interior, full));
    finish(ctx);
}

/// The gauge path (polygons, ellipses, cat's-eyes: row spans bounded by the aperture's row table) against
/// the per-tap first kernel, which evaluates the aperture at every tap of the window disk, on
/// a scene whose near layer crosses the focal plane (windows with sources on both sides, where
/// an odd polygon and its mirror both bound the rows) and at sizes no tile divides.
#[test]
fn gauge_path_matches_per_tap_evaluation_and_is_bit_identical_tiled_or_not() {
    let ctx = gpu();
    let fast = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let per_tap = DrBokehGpu::with_kernel(&ctx, LayerKernel::Baseline).unwrap();
    let (w, h) = (70, 53);
    let mut stack = scene(w, h);
    // Disparity 0.3 -> 0.72 left to right: CoC -10 .. +11 px around focus 0.5 at K = 50.
    stack.layers[0].disparity = (0..w * h).map(|i| 0.3 + 0.006 * (i % w) as f32).collect();
    let apertures = [
        Aperture::polygon(6, 0.0, 0.0).unwrap(),
        Aperture::polygon(5, 10.0, 0.0).unwrap(),
        Aperture::polygon(9, 0.0, 0.5).unwrap(),
        Aperture::polygon(3, 33.0, 0.0).unwrap(),
        Aperture::anamorphic(1.8, 30.0).unwrap(),
        Aperture::cats_eye([0.9, 0.5]).unwrap(),
    ];
    for aperture in apertures {
        let lens = Lens { coc: CocModel::new(50.0, 0.5).unwrap(), aperture: aperture.clone() };
        assert_span_path_matches(&fast, &per_tap, &stack, &lens);
    }
    drop((fast, per_tap));
    finish(ctx);
}

/// The ring path (the disk's row spans split around the obstruction, whose middle is skipped)
/// against the per-tap first kernel, on the disk test's scene (CoC 20-25 px: obstructions of
/// 4-20 px, in-focus occluding centres) and on one whose near layer crosses the focal plane
/// (small CoCs, where the ring fades in and nothing may be skipped).
#[test]
fn ring_path_matches_per_tap_evaluation_and_is_bit_identical_tiled_or_not() {
    let ctx = gpu();
    let fast = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let per_tap = DrBokehGpu::with_kernel(&ctx, LayerKernel::Baseline).unwrap();
    let (w, h) = (70, 53);
    let flat = scene(w, h);
    let mut crossing = flat.clone();
    crossing.layers[0].disparity = (0..w * h).map(|i| 0.3 + 0.006 * (i % w) as f32).collect();
    for inner in [0.2, 0.5, 0.8] {
        let lens = Lens { coc: CocModel::new(50.0, 0.5).unwrap(), aperture: Aperture::ring(inner).unwrap() };
        for stack in [&flat, &crossing] {
            assert_span_path_matches(&fast, &per_tap, stack, &lens);
        }
    }
    drop((fast, per_tap));
    finish(ctx);
}

/// The vignetted apertures (one-pass `--cats-eye`) against their f64 CPU reference, which
/// evaluates every tap with the same shapes, and against the same shader evaluating every tap
/// (no interior sums, no trimmed rows), bit-identical across tile sizes, with the near layer
/// crossing focus (both orientations bound the rows) and at the limit strength 1.5 as well as
/// 0.6:
/// - the disk: the cat's-eye of each 16 px receiver tile, each source's area from its own
///   position (corner eyes at 1.5 with |a| = 0.75, 14% of the disk);
/// - straight-bladed polygons and the ellipse: each tile's base clipped by its vignetting disk
///   and recentred on the centroid from the host's table (src/camera/vignetted.rs), rows from
///   the base's table intersected with the disks', each source's area from the tables around
///   its own shift (the corners' eyes at 1.5 keep a sliver of the base).
#[test]
fn vignetted_apertures_match_cpu_reference_and_per_tap_evaluation() {
    let ctx = gpu();
    let fast = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let full = DrBokehGpu::with_kernel(&ctx, LayerKernel::OptimisedNoInterior).unwrap();
    let crossing = |w: usize, h: usize| {
        let mut stack = scene(w, h);
        stack.layers[0].disparity = (0..w * h).map(|i| 0.3 + 0.006 * (i % w) as f32).collect();
        stack
    };
    let bases = [
        Aperture::Disk,
        Aperture::polygon(6, 0.0, 0.0).unwrap(),
        Aperture::polygon(5, 17.0, 0.0).unwrap(),
        Aperture::anamorphic(1.8, 0.0).unwrap(),
        Aperture::anamorphic(1.8, 70.0).unwrap(),
    ];
    for base in &bases {
        for strength in [0.6, 1.5] {
            let aperture = Aperture::vignetted(base, strength).unwrap();
            // 3x3 tiles at K = 25 (the CPU reference is slow): the same bound as every aperture's.
            let small = crossing(45, 37);
            let lens = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: aperture.clone() };
            let worst = worst_relative(
                &fast.render(&small, &lens, Model::DrBokeh).unwrap(),
                &render_cpu(&small, &lens, Model::DrBokeh).unwrap(),
            );
            assert!(
                worst < 5e-5,
                "{base:?} strength {strength}: worst relative difference {worst} from the CPU reference"
            );
            let lens = Lens { coc: CocModel::new(50.0, 0.5).unwrap(), aperture };
            assert_span_path_matches(&fast, &full, &crossing(70, 53), &lens);
        }
    }
    assert!(
        Aperture::vignetted(&Aperture::polygon(6, 0.0, 0.2).unwrap(), 0.6).is_none(),
        "rounded blades keep the node grid"
    );
    assert!(Aperture::vignetted(&Aperture::ring(0.5).unwrap(), 0.6).is_none(), "the ring keeps the node grid");
    drop((fast, full));
    finish(ctx);
}

/// The kernel path (runs of full-weight cells summed, runs of zero-weight cells skipped,
/// `src/camera/kernel_runs.rs`) against the per-tap first kernel, on a 24^2 five-armed star
/// with soft edges and a hole (full, zero and partial cells in most rows), on the disk test's
/// scene (every radius >= 3/2: zero runs skipped, in-focus occluding centres) and on one whose
/// near layer crosses the focal plane (mirrored and mixed orientations, blended small CoCs).
#[test]
fn kernel_path_matches_per_tap_evaluation_and_is_bit_identical_tiled_or_not() {
    let ctx = gpu();
    let fast = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let per_tap = DrBokehGpu::with_kernel(&ctx, LayerKernel::Baseline).unwrap();
    let n = 24;
    let star = (0..n * n)
        .map(|i| {
            let (u, v) = ((i % n) as f32 / (n - 1) as f32 * 2.0 - 1.0, (i / n) as f32 / (n - 1) as f32 * 2.0 - 1.0);
            let (r, theta) = (u.hypot(v), v.atan2(u));
            let arm = 0.45 + 0.5 * (2.5 * theta).cos().abs();
            if r < 0.15 {
                0.0
            } else {
                ((arm - r) * 8.0).clamp(0.0, 1.0)
            }
        })
        .collect();
    let kernel = Aperture::Kernel(KernelImage::from_weights(n, star).unwrap());
    let (w, h) = (70, 53);
    let flat = scene(w, h);
    let mut crossing = flat.clone();
    crossing.layers[0].disparity = (0..w * h).map(|i| 0.3 + 0.006 * (i % w) as f32).collect();
    // Layers of one disparity each (one kernel sample a tap serves source and centre, span_radii's
    // fourth entry), and the same with one covered pixel moved off it (its tiles and every tile
    // whose window holds it sample twice again).
    let mut even = flat.clone();
    for (layer, disparity) in even.layers.iter_mut().zip([0.9, 0.5, 0.12]) {
        layer.disparity = vec![disparity; w * h];
    }
    let mut one_off = even.clone();
    one_off.layers[0].disparity[14 * w + 15] = 0.93;
    let lens = Lens { coc: CocModel::new(50.0, 0.5).unwrap(), aperture: kernel };
    for stack in [&flat, &crossing, &even, &one_off] {
        assert_span_path_matches(&fast, &per_tap, stack, &lens);
    }
    drop((fast, per_tap));
    finish(ctx);
}

/// A job's warm-up compiles, on the context, every pipeline its render will dispatch, for the
/// aperture it names and for the one its lens character makes (a cat's-eye: the vignetted
/// pipelines), so that a one-shot render can compile them while its file is read. A renderer
/// made after it finds them compiled; before it, the aperture's layer pipeline was not.
#[test]
fn a_jobs_warm_up_compiles_the_pipelines_its_render_dispatches() {
    use lensblur::character::{CatsEye, Character};
    use lensblur::input::CameraRequest;
    use lensblur::job::{JobSpec, RenderJob};
    use lensblur::render::Method;
    let ctx = gpu();
    let cases = [
        (Aperture::Disk, None),
        (Aperture::polygon(6, 0.0, 0.0).unwrap(), None),
        (Aperture::ring(0.4).unwrap(), None),
        (Aperture::polygon(6, 0.0, 0.0).unwrap(), Some(0.6)),
    ];
    for (aperture, cats_eye) in cases {
        let character = Character { cats_eye: cats_eye.map(|s| CatsEye::new(s).unwrap()), ..Character::default() };
        let camera = CameraRequest { aperture: aperture.clone(), ..CameraRequest::default() };
        let job = RenderJob::new(JobSpec { method: Method::DrBokeh, camera, character: character.clone(), ..JobSpec::default() }).unwrap();
        // The lens the render sees, at any CoC.
        let lens = Lens { coc: CocModel::new(7.0, 0.3).unwrap(), aperture };
        let (_, lens) = character.for_method(Method::DrBokeh, &lens);
        let what = format!("{:?}, cat's-eye {cats_eye:?}", lens.aperture);
        assert!(!DrBokehGpu::new(&ctx).unwrap().compiled_for(&lens, Model::DrBokeh).unwrap(), "{what}: compiled before the warm-up");
        job.warm_up(&ctx).unwrap();
        assert!(DrBokehGpu::new(&ctx).unwrap().compiled_for(&lens, Model::DrBokeh).unwrap(), "{what}: not compiled by the warm-up");
    }
    finish(ctx);
}

/// A forward render holds each layer's intermediates one layer at a time: a frame the tiler
/// renders as one tile holds at most 3x the stack's float32 size on the device (issue 44's
/// bound; holding every layer's at once took 5.4x), for a disk and a polygon. Cut into tiles
/// (four of 128 px in one batch), the image is the same. Small tiles hold more than 3x: each
/// uploads its halo, and the buffers of a batch's tiles are held together.
#[test]
fn a_forward_render_holds_at_most_three_times_the_stack_on_the_device() {
    use lensblur::render::drbokeh::RenderOptions;
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = scene(256, 192);
    let stack_bytes = (stack.layers.len() * stack.width * stack.height * 20) as f64;
    for aperture in [Aperture::Disk, Aperture::polygon(6, 0.0, 0.0).unwrap()] {
        let lens = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: aperture.clone() };
        let (whole, untiled) = renderer.render_with(&stack, &lens, Model::DrBokeh, &RenderOptions::default()).unwrap();
        assert_eq!(untiled.tiles, 1, "{aperture:?}: the tiler's plan");
        let ratio = untiled.peak_device_bytes as f64 / stack_bytes;
        assert!(ratio > 1.0 && ratio <= 3.0, "{aperture:?}: peak device memory {ratio:.2}x the stack");
        let options = RenderOptions { tile: Some(128), ..RenderOptions::default() };
        let (tiled, in_tiles) = renderer.render_with(&stack, &lens, Model::DrBokeh, &options).unwrap();
        assert_eq!((in_tiles.tiles, in_tiles.tiles_per_batch), (4, 4), "{aperture:?}: the tiled plan");
        assert_eq!(whole.pixels, tiled.pixels, "{aperture:?}: tiles change the image");
    }
    drop(renderer);
    finish(ctx);
}

/// A render handed a stack memo (a resident session's) keeps Dr.Bokeh's stack scan and, for a
/// frame of one tile, its upload in it and refocuses from them: the images equal renders
/// without one, bit for bit, for focus behind, in and in front of the scene's layers (the
/// straddled tiles read again) and two apertures. A render cut into tiles lets the upload go
/// (its tiles upload their own rects) and still equals the others.
#[test]
fn a_stack_memo_keeps_the_scan_and_the_upload_and_changes_no_pixel() {
    use lensblur::render::drbokeh::{RenderOptions, ResidentStack};
    use lensblur::render::tiler::StackMemo;
    use lensblur::render::{Method, MethodInput, MethodSettings};
    let ctx = gpu();
    let renderer = Method::DrBokeh.prepare(Some(&ctx)).unwrap();
    let stack = scene(80, 64);
    let memo = StackMemo::default();
    let (lo, hi) = stack.disparity_range();
    for (i, focus) in [lo - 0.1, 0.5 * (lo + hi), hi + 0.1, lo].into_iter().enumerate() {
        for aperture in [Aperture::Disk, Aperture::polygon(6, 0.0, 0.0).unwrap()] {
            let lens = Lens { coc: CocModel::new(20.0, focus).unwrap(), aperture: aperture.clone() };
            let render = |memo| {
                let options = RenderOptions { stack_memo: memo, ..RenderOptions::default() };
                renderer.render(MethodInput::Layers(&stack), &lens, &options, &MethodSettings::default()).unwrap()
            };
            let kept = render(Some(&memo));
            assert!(memo.holds::<ResidentStack>(), "render {i}: no scan kept");
            let resident = memo.get_or_insert_with::<ResidentStack>(|| unreachable!("kept above"));
            assert!(resident.holds_upload(), "render {i}: the one-tile frame's upload was not kept");
            assert_eq!(kept.pixels, render(None).pixels, "render {i}, focus {focus}, {aperture:?}");
        }
    }
    // Cut into 32-px tiles, the render uploads each tile's rect and lets the frame's go; the
    // next one-tile render keeps its own again.
    let lens = Lens { coc: CocModel::new(20.0, lo).unwrap(), aperture: Aperture::Disk };
    let render = |memo, tile| {
        let options = RenderOptions { stack_memo: memo, tile, ..RenderOptions::default() };
        renderer.render(MethodInput::Layers(&stack), &lens, &options, &MethodSettings::default()).unwrap()
    };
    let resident = memo.get_or_insert_with::<ResidentStack>(|| unreachable!("kept above"));
    let whole = render(None, None);
    assert_eq!(render(Some(&memo), Some(32)).pixels, whole.pixels, "tiled, from the memo");
    assert!(!resident.holds_upload(), "a tiled render kept the frame's upload");
    assert_eq!(render(Some(&memo), None).pixels, whole.pixels, "one tile again");
    assert!(resident.holds_upload(), "the one-tile render did not keep its upload again");
    drop(resident);
    // A scan of another stack is refused, not rendered from.
    let other = scene(48, 64);
    let gpu = DrBokehGpu::new(&ctx).unwrap();
    let refused =
        gpu.render_resident(&other, &ResidentStack::new(&stack, lo), &lens, Model::DrBokeh, &RenderOptions::default());
    assert!(refused.is_err_and(|e| e.to_string().contains("another stack")), "a mismatched scan was rendered from");
    drop(gpu);
    // One scan served every render: the first's.
    let scans = std::sync::Arc::strong_count(&memo.get_or_insert_with::<ResidentStack>(|| unreachable!("the scan was not kept")));
    assert_eq!(scans, 2, "the memo's and this one");
    drop(renderer);
    finish(ctx);
}

/// The optimised kernel's render of `stack` (returned) against the baseline kernel's, which
/// gathers and writes every pixel of every layer: within 5e-5 relative, and the same bits cut
/// into 32-px frame tiles (`tiles` of them), where each tile folds and skips over its own core.
fn assert_skips_are_exact(optimised: &DrBokehGpu, baseline: &DrBokehGpu, stack: &LayerStack, lens: &Lens, tiles: usize, label: &str) -> lensblur::image::Image {
    use lensblur::render::drbokeh::RenderOptions;
    let fast = optimised.render(stack, lens, Model::DrBokeh).unwrap();
    let first = baseline.render(stack, lens, Model::DrBokeh).unwrap();
    let worst = worst_relative(&fast, &first);
    assert!(worst < 5e-5, "{label}: worst relative difference {worst} from the baseline kernel");
    let options = RenderOptions { tile: Some(32), ..RenderOptions::default() };
    let (tiled, stats) = optimised.render_with(stack, lens, Model::DrBokeh, &options).unwrap();
    assert_eq!(stats.tiles, tiles, "{label}: the tiled plan");
    assert_eq!(tiled.pixels, fast.pixels, "{label}: the tiles change the image");
    fast
}

/// A layer pass skips the pixels the layers in front already hide completely (their
/// transmittance exactly 0: an opaque front layer's interior, where its V is exactly 1). The
/// skip is exact: with an opaque 80x64 square in front of a HDR back layer, the optimised
/// kernel stays within the span paths' 5e-5 of the baseline kernel (which gathers every pixel),
/// the square's interior is opaque (alpha exactly 1), and scrambling the back layer where the
/// square hides it beyond any tap's reach changes no pixel, nor does cutting the frame into
/// 32-px tiles. Square in focus (CoC 1 px: the in-layer occlusion terms) and blurred (3 px),
/// back 8-10 px; a disk and a polygon.
#[test]
fn pixels_hidden_by_opaque_layers_in_front_change_nothing() {
    use lensblur::image::Image;
    use lensblur::stack::Layer;
    let ctx = gpu();
    let optimised = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let baseline = DrBokehGpu::with_kernel(&ctx, LayerKernel::Baseline).unwrap();
    let (w, h) = (96, 80);
    let square = |x: usize, y: usize| (8..88).contains(&x) && (8..72).contains(&y);
    // 20 px inside the square: the front's V is below 1 at most ~5 px inside, and the back
    // layer's taps from there reach less than 12 px further.
    let deep = |x: usize, y: usize| (28..68).contains(&x) && (28..52).contains(&y);
    let stack_with = |back: &dyn Fn(usize, usize) -> [f32; 4]| {
        let front = Layer {
            name: "front".into(),
            rgba: Image::from_fn(w, h, |x, y| if square(x, y) { [0.8, 0.3, 0.1, 1.0] } else { [0.0; 4] }),
            disparity: vec![0.65; w * h],
        };
        let far = Layer { name: "far".into(), rgba: Image::from_fn(w, h, back), disparity: vec![0.1; w * h] };
        LayerStack::new(w, h, vec![front, far]).expect("a valid stack")
    };
    let back = |x: usize, y: usize| {
        let v = ((x * 3 + y * 5) % 17) as f32 / 17.0;
        let highlight = if (x * 7 + y * 13) % 29 == 0 { 40.0 } else { 0.0 };
        [v + highlight, 0.5 * v, 1.0 - v, 1.0]
    };
    let scrambled = |x: usize, y: usize| if deep(x, y) { [1000.0, 0.0, 7.0, 1.0] } else { back(x, y) };
    let (stack, other) = (stack_with(&back), stack_with(&scrambled));
    for focus in [0.6, 0.5] {
        for aperture in [Aperture::Disk, Aperture::polygon(6, 0.0, 0.0).unwrap()] {
            let label = format!("focus {focus}, {aperture:?}");
            let lens = Lens { coc: CocModel::new(20.0, focus).unwrap(), aperture: aperture.clone() };
            let fast = assert_skips_are_exact(&optimised, &baseline, &stack, &lens, 9, &label);
            let translucent = (0..w * h).filter(|i| deep(i % w, i / w) && fast.pixels[*i][3] != 1.0).count();
            assert_eq!(translucent, 0, "{label}: deep inside the square, alpha is not exactly 1");
            let changed = optimised.render(&other, &lens, Model::DrBokeh).unwrap();
            let differing = changed.pixels.iter().zip(&fast.pixels).filter(|(a, b)| a != b).count();
            assert_eq!(differing, 0, "{label}: {differing} pixels changed with the hidden back layer");
        }
    }
    drop((optimised, baseline));
    finish(ctx);
}

/// Tiles a layer's sources do not reach (`EMPTY_WINDOW`) are left alone by its pass when the
/// layers fold one after another (`drbokeh_layer_adds_nothing`): a sparse middle layer (a disc
/// covering a few of the frame's tiles) between a small front square and a full back layer.
/// The optimised kernel stays within 5e-5 of the baseline kernel (which writes every pixel of
/// every layer), and 32-px frame tiles give the same bits. Middle layer in focus (its own tiles'
/// windows are 0: a skip of anything but the empty ones loses the disc) and blurred (4 px).
#[test]
fn tiles_a_layer_does_not_reach_are_left_alone() {
    use lensblur::image::Image;
    use lensblur::render::drbokeh::bounds::{windows_and_ranges, EMPTY_WINDOW};
    use lensblur::render::drbokeh::Params;
    use lensblur::stack::Layer;
    let ctx = gpu();
    let optimised = DrBokehGpu::with_kernel(&ctx, LayerKernel::Optimised).unwrap();
    let baseline = DrBokehGpu::with_kernel(&ctx, LayerKernel::Baseline).unwrap();
    let (w, h) = (112, 96);
    let layer = |name: &str, disparity: f32, rgba: &dyn Fn(usize, usize) -> [f32; 4]| Layer {
        name: name.into(),
        rgba: Image::from_fn(w, h, rgba),
        disparity: vec![disparity; w * h],
    };
    let front = layer("front", 0.65, &|x, y| {
        if (16..40).contains(&x) && (16..40).contains(&y) { [0.8, 0.3, 0.1, 1.0] } else { [0.0; 4] }
    });
    // A disc with a soft (half-covered) rim, bright at its centre.
    let middle = layer("middle", 0.4, &|x, y| {
        let d = ((x as f32 - 80.0).powi(2) + (y as f32 - 64.0).powi(2)).sqrt();
        let a = (10.5 - d).clamp(0.0, 1.0);
        let glow = if d < 2.0 { 30.0 } else { 1.0 };
        [0.1 * a * glow, 0.9 * a, 0.4 * a, a]
    });
    let back = layer("back", 0.1, &|x, y| {
        let v = ((x * 3 + y * 5) % 17) as f32 / 17.0;
        [v, 0.5 * v, 1.0 - v, 1.0]
    });
    let stack = LayerStack::new(w, h, vec![front, middle, back]).expect("a valid stack");
    for focus in [0.4, 0.2] {
        for aperture in [Aperture::Disk, Aperture::polygon(5, 0.0, 0.0).unwrap()] {
            let label = format!("focus {focus}, {aperture:?}");
            let lens = Lens { coc: CocModel::new(20.0, focus).unwrap(), aperture: aperture.clone() };
            // The test needs both kinds of the middle layer's tiles.
            let params = Params::new(&stack, &lens, Model::DrBokeh).unwrap();
            let (windows, _) = windows_and_ranges(&params, &stack);
            let middle = &windows[params.tiles_x * params.tiles_y..2 * params.tiles_x * params.tiles_y];
            let empty = middle.iter().filter(|&&w| w == EMPTY_WINDOW).count();
            assert!(empty > middle.len() / 2 && empty < middle.len(), "{label}: {empty} of {} tiles empty", middle.len());
            assert_skips_are_exact(&optimised, &baseline, &stack, &lens, 12, &label);
        }
    }
    drop((optimised, baseline));
    finish(ctx);
}
