//! Lens character controls (issue 12): each test states the physical behaviour it proves.
//! GPU tests render with Dr.Bokeh on small frames (lavapipe is a CPU driver).
mod common;

use std::process::Command;

use common::{finish, gpu};
use lensblur::camera::{Aperture, CocModel};
use lensblur::character::{debug, kernels, render_cats_eye, render_chromatic, Bloom, BlurRemap, CatsEye, Character};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::vdslr::FocusField;
use lensblur::render::{Lens, Method};
use lensblur::stack::{write_stack, Layer, LayerStack, StackWriteOptions};

/// One opaque black layer at disparity 0 with a bright pixel at `(px, py)` in each listed spot.
fn point_lights(w: usize, h: usize, spots: &[(usize, usize)]) -> LayerStack {
    let rgba = Image::from_fn(w, h, |x, y| if spots.contains(&(x, y)) { [100.0, 100.0, 100.0, 1.0] } else { [0.0, 0.0, 0.0, 1.0] });
    LayerStack::new(w, h, vec![Layer { name: "lights".into(), rgba, disparity: vec![0.0; w * h] }]).unwrap()
}

/// Focus at disparity 0.5 with K = 2r: the disparity-0 lights get a CoC of radius `r`.
fn lens(r: f32, aperture: Aperture) -> Lens {
    Lens { coc: CocModel::new(2.0 * r, 0.5).unwrap(), aperture }
}

/// Second moments of channel 0 in the window `[x0, x1) x [y0, y1)`: (cxx, cyy, cxy) about the centroid.
fn moments(image: &Image, x0: usize, y0: usize, x1: usize, y1: usize) -> (f64, f64, f64) {
    let (mut s, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
    let mut taps = Vec::new();
    for y in y0..y1 {
        for x in x0..x1 {
            let v = image.get(x, y)[0].max(0.0) as f64;
            taps.push((x as f64, y as f64, v));
            s += v;
            sx += v * x as f64;
            sy += v * y as f64;
        }
    }
    let (cx, cy) = (sx / s, sy / s);
    taps.iter().fold((0.0, 0.0, 0.0), |(a, b, c), &(x, y, v)| {
        (a + v * (x - cx).powi(2) / s, b + v * (y - cy).powi(2) / s, c + v * (x - cx) * (y - cy) / s)
    })
}

/// Variances of channel 0 in the 16x16 window at `(x0, y0)` along the main diagonal (radial
/// for a light near the top-left corner) and across it (tangential).
fn diagonal_variances(image: &Image, x0: usize, y0: usize) -> (f64, f64) {
    let (xx, yy, xy) = moments(image, x0, y0, x0 + 16, y0 + 16);
    ((xx + yy) / 2.0 + xy, (xx + yy) / 2.0 - xy)
}

/// Radius of a uniform disk with the same second moment: E[x^2 + y^2] = R^2 / 2.
fn measured_radius(image: &Image) -> f64 {
    let (xx, yy, _) = moments(image, 0, 0, image.width, image.height);
    (2.0 * (xx + yy)).sqrt()
}

fn render(renderer: &DrBokehGpu, stack: &LayerStack, lens: &Lens) -> lensblur::Result<Image> {
    renderer.render(stack, lens, Model::DrBokeh)
}

#[test]
fn blur_remap_is_monotonic_scales_each_side_and_clamps() {
    let coc = CocModel::new(10.0, 0.5).unwrap();
    let remap = BlurRemap { near: 2.0, far: 0.5, max_px: Some(3.0) };
    let mut previous = f32::NEG_INFINITY;
    for i in 0..=200 {
        let d = i as f32 / 200.0;
        let mapped = remap.disparity(d, &coc);
        // Monotonic: a nearer surface never maps behind a farther one, so occlusion order holds.
        assert!(mapped >= previous, "d = {d}: {mapped} < {previous}");
        assert!(coc.radius(mapped) <= 3.0 + 1e-5, "clamp exceeded at d = {d}");
        previous = mapped;
    }
    let free = BlurRemap { near: 2.0, far: 0.5, max_px: None };
    // 1e-6: f32 rounding of a handful of operations on values near 1.
    assert!((coc.signed_radius(free.disparity(0.6, &coc)) - 2.0).abs() < 1e-5, "near blur doubles (1 px -> 2 px)");
    assert!((coc.signed_radius(free.disparity(0.3, &coc)) + 1.0).abs() < 1e-5, "far blur halves (-2 px -> -1 px)");
    assert_eq!(free.disparity(0.5, &coc), 0.5, "the focal plane stays in focus");
    assert!(BlurRemap { near: -1.0, ..BlurRemap::default() }.validate().is_err());
}

#[test]
fn bloom_boosts_only_highlights_smoothly_and_keeps_coverage() {
    let bloom = Bloom::parse("0.8:5").unwrap();
    assert_eq!(bloom.factor(0.5), 1.0, "below the threshold nothing changes");
    assert_eq!(bloom.factor(0.8), 1.0);
    assert_eq!(bloom.factor(1.0), 5.0, "a clipped LDR highlight gets the full gain");
    let mut previous = 1.0;
    for i in 0..=100 {
        let f = bloom.factor(0.8 + 0.2 * i as f32 / 100.0);
        // Smooth ramp: monotonic and no jump larger than the Hermite slope allows (1.5 x 4 / 100).
        assert!(f >= previous && f - previous < 0.061, "step at {i}: {previous} -> {f}");
        previous = f;
    }
    // A half-covered white pixel is as bright as a covered one: judged on straight colour.
    assert_eq!(bloom.pixel([0.5, 0.5, 0.5, 0.5]), [2.5, 2.5, 2.5, 0.5]);
    assert_eq!(bloom.pixel([0.2, 0.1, 0.0, 1.0]), [0.2, 0.1, 0.0, 1.0]);
    assert!(Bloom::parse("0.9:0.5").is_err() && Bloom::parse("x").is_err());
}

#[test]
fn aperture_parse_accepts_anamorphic_and_ring_and_keeps_old_forms() {
    assert_eq!(Aperture::parse("disk").unwrap(), Aperture::Disk);
    assert!(matches!(Aperture::parse("polygon:6:rotation=15").unwrap(), Aperture::Polygon { blades: 6, .. }));
    let ellipse = Aperture::parse("anamorphic:2:rotation=90").unwrap();
    assert!(matches!(ellipse, Aperture::Ellipse { .. }), "a gauge shape, not a kernel image: {ellipse:?}");
    // Rotated by 90 degrees the long axis is vertical: a point at v = 0.8 is inside, u = 0.8
    // outside (gauge 1.6), and the area is half the disk's.
    assert!(ellipse.gauge(0.0, 0.8) < 0.81 && ellipse.gauge(0.8, 0.0) > 1.59);
    assert!((ellipse.relative_area() - 0.5).abs() < 1e-6);
    // The ring has its own closed form (no kernel image): dark centre, open annulus.
    let ring = Aperture::parse("ring:0.5").unwrap();
    assert_eq!(ring, Aperture::Ring { inner: 0.5 });
    assert!(ring.weight(0.0, 0.0) == 0.0 && ring.weight(0.75, 0.0) == 1.0);
    for bad in ["anamorphic", "anamorphic:0.5", "anamorphic:2:spin=3", "ring", "ring:1.5", "ring:0.5:2", "donut"] {
        assert!(Aperture::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn cats_eye_kernel_is_round_on_axis_and_narrower_radially_off_axis() {
    let round = kernels::cats_eye(&Aperture::Disk, [0.0, 0.0]).unwrap();
    let clipped = kernels::cats_eye(&Aperture::Disk, [0.8, 0.0]).unwrap();
    // On axis: full disk; off axis along +u: the lens of two unit disks 0.8 apart, re-centred:
    // half-width 1 - 0.4 = 0.6 along u, sqrt(1 - 0.16) = 0.92 along v.
    assert!(round.sample(0.9, 0.0) > 0.9 && round.sample(0.0, 0.9) > 0.9);
    assert!(clipped.sample(0.7, 0.0) < 0.05 && clipped.sample(-0.7, 0.0) < 0.05, "narrow radially, symmetric");
    assert!(clipped.sample(0.0, 0.85) > 0.9, "long tangentially");
}

#[test]
fn layer_assignment_coc_sign_and_focus_peaking_describe_the_scene() {
    let (w, h) = (32, 16);
    let front = Image::from_fn(w, h, |x, _| if x < 16 { [1.0, 1.0, 1.0, 1.0] } else { [0.0; 4] });
    let back = Image::filled(w, h, [0.2, 0.2, 0.2, 1.0]);
    let stack = LayerStack::new(w, h, vec![
        Layer { name: "front".into(), rgba: front, disparity: vec![0.9; w * h] },
        Layer { name: "back".into(), rgba: back, disparity: vec![0.1; w * h] },
    ]).unwrap();
    let lens = Lens { coc: CocModel::new(10.0, 0.5).unwrap(), aperture: Aperture::Disk };
    let layers = debug::layer_assignment(&stack);
    assert_eq!((layers[8 * w + 4], layers[8 * w + 24]), (Some(0), Some(1)));
    let coc = debug::coc_map(&stack, &lens, &FocusField::Plane).unwrap();
    assert!(coc[8 * w + 4] > 0.0 && coc[8 * w + 24] < 0.0, "near is positive, far negative");
    let colours = debug::coc_image(w, h, &coc);
    assert!(colours.get(4, 8)[0] > colours.get(4, 8)[2] && colours.get(24, 8)[2] > colours.get(24, 8)[0], "near warm, far cool");
    // A sharp step is peaked; the same step as a 16-px ramp (blurred) is not.
    let sharp = Image::from_fn(w, h, |x, _| if x < 16 { [1.0; 4] } else { [0.0, 0.0, 0.0, 1.0] });
    let soft = Image::from_fn(w, h, |x, _| { let v = (x as f32 / 31.0).min(1.0); [v, v, v, 1.0] });
    assert!(debug::focus_peaking(&sharp)[8 * w + 15] && !debug::focus_peaking(&soft).iter().any(|&p| p));
    // Visibility of the opaque front layer is 1 deep inside it, 0 far outside (CoC 4 px).
    let v = debug::visibility(&stack, &lens).unwrap();
    assert!((v[0].get(4, 8)[0] - 1.0).abs() < 1e-3 && v[0].get(28, 8)[0] < 1e-3);
}

#[test]
fn focus_at_picks_the_clicked_layer_which_renders_sharp() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let (w, h) = (48, 48);
    let texture = |x: usize, y: usize| ((x * 7 + y * 13) % 11) as f32 / 11.0;
    let square = Image::from_fn(w, h, |x, y| {
        if (12..36).contains(&x) && (12..36).contains(&y) { [texture(x, y), 0.5, 1.0 - texture(x, y), 1.0] } else { [0.0; 4] }
    });
    let wall = Image::from_fn(w, h, |x, y| [0.3, texture(y, x), 0.6, 1.0]);
    let stack = LayerStack::new(w, h, vec![
        Layer { name: "square".into(), rgba: square.clone(), disparity: vec![0.8; w * h] },
        Layer { name: "wall".into(), rgba: wall.clone(), disparity: vec![0.2; w * h] },
    ]).unwrap();
    let lens = Lens { coc: CocModel::new(10.0, 0.5).unwrap(), aperture: Aperture::Disk };
    let render = |s: &LayerStack, l: &Lens| renderer.render(s, l, Model::DrBokeh);
    for (click, sharp, region) in [([24, 24], &square, (18, 30)), ([2, 2], &wall, (0, 4))] {
        let character = Character { focus_at: Some(click), ..Character::default() };
        let (prepared, focused) = character.prepare(&stack, &lens).unwrap();
        let image = character.render_prepared(&render, &prepared, &focused).unwrap();
        let mut worst = 0.0f32;
        for y in region.0..region.1 {
            for x in region.0..region.1 {
                (0..4).for_each(|c| worst = worst.max((image.get(x, y)[c] - sharp.get(x, y)[c]).abs()));
            }
        }
        // The clicked layer is exactly in focus: its pixels (away from the other layer's blur
        // reach of 3 px) come out unchanged up to f32 rounding.
        assert!(worst < 1e-4, "click {click:?}: worst difference from the sharp layer {worst}");
    }
    drop(renderer);
    finish(ctx);
}

#[test]
fn blur_multipliers_scale_and_clamp_the_measured_radius_of_a_point_light() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = point_lights(64, 64, &[(32, 32)]);
    let base = lens(6.0, Aperture::Disk);
    let render_with = |remap: BlurRemap| {
        let character = Character { remap, ..Character::default() };
        let (s, l) = character.prepare(&stack, &base).unwrap();
        character.render_prepared(&|s: &LayerStack, l: &Lens| render(&renderer, s, l), &s, &l).unwrap()
    };
    let plain = measured_radius(&render_with(BlurRemap::default()));
    let doubled = measured_radius(&render_with(BlurRemap { far: 2.0, near: 0.25, max_px: None }));
    let clamped = measured_radius(&render_with(BlurRemap { far: 2.0, near: 1.0, max_px: Some(3.0) }));
    // Moment radius of the anti-aliased disk: measured 6.01, 12.00, 3.05 px; 5% tolerance
    // covers rim sampling differences between drivers.
    assert!((plain - 6.0).abs() < 0.3, "plain radius {plain}");
    assert!((doubled / plain - 2.0).abs() < 0.1, "far x2 (near multiplier irrelevant): {doubled} vs {plain}");
    assert!((clamped - 3.0).abs() < 0.15, "clamped to 3 px: {clamped}");
    drop(renderer);
    finish(ctx);
}

#[test]
fn ring_aperture_point_light_has_a_dark_centre_and_anamorphic_one_is_wider_by_the_squeeze() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = point_lights(64, 64, &[(32, 32)]);
    let ring = render(&renderer, &stack, &lens(12.0, Aperture::parse("ring:0.6").unwrap())).unwrap();
    let (centre, rim) = (ring.get(32, 32)[0], ring.get(32 + 10, 32)[0]);
    // Mirror obstruction of 0.6 radius: no light reaches the centre, the annulus is lit.
    assert!(centre < 0.05 * rim, "centre {centre}, annulus {rim}");
    let oval = render(&renderer, &stack, &lens(12.0, Aperture::parse("anamorphic:2").unwrap())).unwrap();
    let (xx, yy, _) = moments(&oval, 0, 0, 64, 64);
    let ratio = (xx / yy).sqrt();
    // Semi-axes 12.5 and 6.25 px plus half a pixel of rim each: 1.92 expected; 7% tolerance.
    assert!((ratio - 1.92).abs() < 0.14, "width/height {ratio}");
    drop(renderer);
    finish(ctx);
}

#[test]
fn cats_eye_bokeh_is_round_at_the_centre_and_lens_shaped_at_a_corner() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = point_lights(80, 80, &[(40, 40), (8, 8)]);
    let eye = CatsEye { strength: 1.0, grid: 3 };
    let image = render_cats_eye(&|s: &LayerStack, l: &Lens| render(&renderer, s, l), &stack, &lens(6.0, Aperture::Disk), &eye).unwrap();
    let axes = |x0, y0| diagonal_variances(&image, x0, y0);
    let (radial, tangential) = axes(32, 32);
    assert!((radial / tangential - 1.0).abs() < 0.05, "centre is round: {radial} vs {tangential}");
    let (radial, tangential) = axes(0, 0);
    // Corner: the second disk shifted ~0.8 radius toward the corner; radial extent ~0.6 of the
    // tangential one (variance ratio ~0.4), blended with the milder node inward.
    assert!(radial / tangential < 0.7, "corner is narrower radially: {radial} vs {tangential}");
    drop(renderer);
    finish(ctx);
}

#[test]
fn cats_eye_grid_blends_to_the_whole_frame_render_when_the_shape_does_not_vary() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let (w, h) = (56, 40);
    let front = Image::from_fn(w, h, |x, y| if (10..30).contains(&x) && (8..28).contains(&y) { [0.9, 0.3, 0.1, 1.0] } else { [0.0; 4] });
    let back = Image::from_fn(w, h, |x, y| { let v = ((x * 5 + y * 3) % 7) as f32 / 7.0; [v, 1.0 - v, 0.5, 1.0] });
    let stack = LayerStack::new(w, h, vec![
        Layer { name: "front".into(), rgba: front, disparity: vec![0.9; w * h] },
        Layer { name: "back".into(), rgba: back, disparity: (0..w * h).map(|i| 0.1 + 0.002 * (i % w) as f32).collect() },
    ]).unwrap();
    let base = Lens { coc: CocModel::new(12.0, 0.5).unwrap(), aperture: Aperture::Disk };
    // Strength 0: every node has the same shape, so crops + halos + tents must reproduce the
    // single whole-frame render with that shape: a disk's cat's-eye (a gauge shape), and a
    // polygon's (kernel images).
    let polygon = Lens { aperture: Aperture::polygon(5, 0.0, 0.0).unwrap(), ..base.clone() };
    for (lens, shape) in [
        (&base, Aperture::cats_eye([0.0, 0.0]).unwrap()),
        (&polygon, Aperture::Kernel(kernels::cats_eye(&polygon.aperture, [0.0, 0.0]).unwrap())),
    ] {
        let whole = render(&renderer, &stack, &Lens { aperture: shape, ..base.clone() }).unwrap();
        let tiled = render_cats_eye(&|s: &LayerStack, l: &Lens| render(&renderer, s, l), &stack, lens, &CatsEye { strength: 0.0, grid: 4 }).unwrap();
        // Same taps in the same order per pixel; only tent-weight rounding differs (measured 1.2e-7).
        let worst = common::max_abs_diff(&whole, &tiled);
        assert!(worst < 1e-6, "{:?}: tiled cat's-eye differs from the whole frame by {worst}", lens.aperture);
    }
    drop(renderer);
    finish(ctx);
}

#[test]
fn chromatic_aberration_fringes_defocused_edges_and_keeps_focused_ones_neutral() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let (w, h) = (64, 16);
    let rgba = Image::from_fn(w, h, |x, _| if x < 32 { [1.0, 1.0, 1.0, 1.0] } else { [0.0, 0.0, 0.0, 1.0] });
    let stack = LayerStack::new(w, h, vec![Layer { name: "edge".into(), rgba, disparity: vec![0.0; w * h] }]).unwrap();
    let render_fn = |s: &LayerStack, l: &Lens| render(&renderer, s, l);
    let spread = |image: &Image, c: usize| (0..w).filter(|&x| (0.02..0.98).contains(&image.get(x, 8)[c])).count() as i64;
    // Out of focus (G: 6 px): R focuses nearer (+3 px of CoC: 9 px), B farther (3 px).
    let defocused = render_chromatic(&render_fn, &stack, &lens(6.0, Aperture::Disk), [3.0, 0.0, -3.0]).unwrap();
    let (r, g, b) = (spread(&defocused, 0), spread(&defocused, 1), spread(&defocused, 2));
    // Transition widths ~2 r (18, 12, 6 px) minus the near-0/near-1 tails: measured 16, 10, 6.
    assert!(r > g + 3 && g > b + 3, "R {r}, G {g}, B {b} transition widths");
    let flat = defocused.get(4, 8);
    assert!(flat[..3].iter().all(|v| (v - 1.0).abs() < 1e-4), "white far from the edge stays white: {flat:?}");
    // In focus (G: 0 px) with +-0.3 px offsets: sub-pixel CoCs, the edge stays neutral.
    let focused_lens = Lens { coc: CocModel::new(12.0, 0.0).unwrap(), aperture: Aperture::Disk };
    let focused = render_chromatic(&render_fn, &stack, &focused_lens, [0.3, 0.0, -0.3]).unwrap();
    let worst = focused.pixels.iter().map(|p| (p[0] - p[2]).abs().max((p[0] - p[1]).abs())).fold(0.0, f32::max);
    let fringe = defocused.pixels.iter().map(|p| (p[0] - p[2]).abs()).fold(0.0, f32::max);
    // Measured: 0 in focus (sub-pixel CoCs leave pixels exact), 0.30 out of focus.
    assert!(worst < 0.02 && fringe > 0.2, "in focus R-B up to {worst}, defocused {fringe}");
    drop(renderer);
    finish(ctx);
}

#[test]
fn cli_renders_with_every_character_flag_and_writes_debug_views() {
    let dir = common::ScratchDir::new("character-cli");
    let (w, h) = (32, 24);
    let subject = Image::from_fn(w, h, |x, y| if (8..20).contains(&x) && (6..18).contains(&y) { [0.9, 0.2, 0.1, 1.0] } else { [0.0; 4] });
    let wall = Image::from_fn(w, h, |x, y| { let c = if (x / 4 + y / 4) % 2 == 0 { 0.9 } else { 0.1 }; [c, c, c, 1.0] });
    let stack = LayerStack::new(w, h, vec![
        Layer { name: "subject".into(), rgba: subject, disparity: vec![0.5; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.25; w * h] },
    ]).unwrap();
    let input = dir.join("shot.exr");
    write_stack(&input, &stack, &StackWriteOptions::default()).unwrap();
    let debug_dir = dir.join("debug");
    let flags = ["--blur", "16", "--focus-disparity", "0.25", "--focus-at", "12,10", "--near-blur", "1.5", "--far-blur", "0.5",
        "--max-blur", "5", "--bloom", "0.8:3", "--chromatic", "-1,0,1"];
    let render = |out: &str, extra: &[&str]| {
        let output = Command::new(env!("CARGO_BIN_EXE_lensblur"))
            .args(["render", input.to_str().unwrap(), "-o", dir.join(out).to_str().unwrap(), "--method", "drbokeh"])
            .args(flags)
            .args(extra)
            .env("LENSBLUR_VALIDATION", "1")
            .output()
            .unwrap();
        assert!(output.status.success(), "lensblur failed: {}", String::from_utf8_lossy(&output.stderr));
        lensblur::stack::read_rgba(&dir.join(out), None, 1 << 24).unwrap()
    };
    let shaped = render("out.exr", &["--cats-eye", "0.5", "--aperture", "ring:0.3", "--debug-out", debug_dir.to_str().unwrap()]);
    for name in ["coc.png", "layers.png", "focus_peaking.png", "visibility_0_subject.png", "visibility_1_wall.png"] {
        assert!(debug_dir.join(name).is_file(), "missing debug view {name}");
    }
    // The aperture and the cat's-eye reach the renderer through every other control: the
    // wall's 5 px blur of a 4 px checker changes visibly with the shape (measured up to 0.17).
    let plain = render("plain.exr", &[]);
    assert!(common::max_abs_diff(&shaped, &plain) > 0.05, "ring + cat's-eye changed nothing");
    let bad = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["render", input.to_str().unwrap(), "-o", dir.join("bad.exr").to_str().unwrap(), "--method", "oracle"])
        .args(["--blur", "16", "--focus-disparity", "0.25", "--focus-at", "99,3"])
        .output()
        .unwrap();
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("outside"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Renders `stack` with the CLI (validation on) and reads the result back.
fn cli_render(stack: &LayerStack, name: &str, flags: &[&str]) -> Image {
    let dir = common::ScratchDir::new(&format!("character-{name}"));
    let (input, out) = (dir.join("in.exr"), dir.join("out.exr"));
    write_stack(&input, stack, &StackWriteOptions::default()).unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["render", input.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(flags)
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(output.status.success(), "lensblur {flags:?}: {}", String::from_utf8_lossy(&output.stderr));
    let image = lensblur::stack::read_rgba(&out, None, 1 << 24).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    image
}

/// Every method draws the aperture it is given (none falls back to a disk silently): a point
/// light seen through a mirror lens (ring:0.6, CoC 12 px) has a dark centre and a lit annulus,
/// and with cat's-eye vignetting the bokeh at a corner is narrower radially than across.
#[test]
fn every_method_honours_kernel_apertures_and_cats_eye() {
    // 3x3 lights, so that ray-traced methods hit them with a few of their lens samples per pixel.
    let lights = |w: usize, h: usize, spots: &[(usize, usize)]| {
        let near = |x: usize, y: usize| spots.iter().any(|&(sx, sy)| x.abs_diff(sx) <= 1 && y.abs_diff(sy) <= 1);
        let spots: Vec<(usize, usize)> = (0..w * h).map(|i| (i % w, i / w)).filter(|&(x, y)| near(x, y)).collect();
        point_lights(w, h, &spots)
    };
    let (ring_scene, eye_scene) = (lights(64, 64, &[(32, 32)]), lights(80, 80, &[(40, 40), (9, 9)]));
    let mean_over = |image: &Image, r0: f32, r1: f32| {
        let taps: Vec<f32> = (0..64 * 64)
            .filter(|&i| (r0..r1).contains(&((i % 64) as f32 - 32.0).hypot((i / 64) as f32 - 32.0)))
            .map(|i| image.pixels[i][0])
            .collect();
        taps.iter().sum::<f32>() / taps.len() as f32
    };
    // GaussPSF blurs with a Gaussian, which has no shape: it refuses any aperture but the disk
    // (src/render/gausspsf.rs tests), so it is the one method left out here.
    for method in Method::ALL.iter().filter(|m| **m != Method::GaussPsf).map(|m| m.name()) {
        // Disparity 0, focus 0.5: K = 24 gives the light a 12 px CoC, K = 12 a 6 px one.
        let flags = |k: &'static str, extra: &[&'static str]| {
            [&["--method", method, "--blur", k, "--focus-disparity", "0.5"][..], extra].concat()
        };
        let ring = cli_render(&ring_scene, &format!("ring-{method}"), &flags("24", &["--aperture", "ring:0.6"]));
        let (centre, annulus) = (mean_over(&ring, 0.0, 3.0), mean_over(&ring, 9.0, 11.0));
        // The obstruction covers 0.6 of the 12 px radius: nothing within 7.2 px minus the
        // light's 1.5 px half-width reaches the centre (measured 0 for every method; 5% leaves
        // room for the soft rims of the gathers, about a pixel wide).
        assert!(centre < 0.05 * annulus, "{method}: centre {centre}, annulus {annulus}");
        let eye = cli_render(&eye_scene, &format!("eye-{method}"), &flags("12", &["--cats-eye", "1.0"]));
        let axes = |x0, y0| diagonal_variances(&eye, x0, y0);
        let (radial, tangential) = axes(32, 32);
        // At the centre the clipping disk is not shifted: round (measured within 1.3%, the
        // ray-traced methods' sampling noise).
        assert!((radial / tangential - 1.0).abs() < 0.1, "{method}: centre bokeh {radial} vs {tangential}");
        let (radial, tangential) = axes(0, 0);
        // At the corner the clipping disk is shifted ~0.8 radius outward: the lens-shaped pupil
        // is ~0.6 as wide radially (variance ratio ~0.4), blended with the next node inward
        // (measured 0.58 to 0.62).
        assert!(radial / tangential < 0.7, "{method}: corner bokeh {radial} vs {tangential}");
    }
}

/// Bloom on LDR input: a clipped highlight (straight value 1.0) on an out-of-focus wall
/// spreads into a dim, flat bokeh ball; with `--bloom 0.8:4` the same ball carries 4 times
/// the light, while an in-focus card below the threshold is untouched.
#[test]
fn bloom_makes_a_clipped_highlight_a_bright_bokeh_ball_and_leaves_darker_pixels_alone() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let (w, h) = (64, 48);
    // Black wall (disparity 0, CoC 8 px) with a 3x3 clipped highlight at (44, 24); an in-focus
    // grey card (0.5 < 0.8) on the left.
    let wall = Image::from_fn(w, h, |x, y| if (43..46).contains(&x) && (23..26).contains(&y) { [1.0; 4] } else { [0.0, 0.0, 0.0, 1.0] });
    let card = Image::from_fn(w, h, |x, y| if x < 20 && (10..38).contains(&y) { [0.5, 0.4, 0.3, 1.0] } else { [0.0; 4] });
    let stack = LayerStack::new(w, h, vec![
        Layer { name: "card".into(), rgba: card.clone(), disparity: vec![0.5; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.0; w * h] },
    ]).unwrap();
    let lens = lens(8.0, Aperture::Disk);
    let render_with = |bloom: Option<Bloom>| {
        let character = Character { bloom, ..Character::default() };
        let (s, l) = character.prepare(&stack, &lens).unwrap();
        character.render_prepared(&|s: &LayerStack, l: &Lens| render(&renderer, s, l), &s, &l).unwrap()
    };
    let (plain, bloomed) = (render_with(None), render_with(Some(Bloom::parse("0.8:4").unwrap())));
    let ball = |image: &Image, radius: f32| {
        let inside = |x: usize, y: usize| (x as f32 - 44.0).powi(2) + (y as f32 - 24.0).powi(2) < radius * radius;
        let values: Vec<f32> = (0..w * h).filter(|&i| inside(i % w, i / w)).map(|i| image.pixels[i][0]).collect();
        values
    };
    // Without bloom: 9 px of light over a 201 px disk, a dim ball (~0.045) with a flat top: the
    // 3x3 source convolved with the r = 8 disk is constant within 5 px of its centre, up to the
    // anti-aliased rim's coverage (measured spread 1e-6).
    let top = ball(&plain, 5.0);
    let mean = top.iter().sum::<f32>() / top.len() as f32;
    assert!(mean < 0.06, "dim without bloom: {mean}");
    assert!(top.iter().all(|v| (v - mean).abs() < 0.05 * mean), "flat top without bloom: mean {mean}");
    // With bloom: each highlight pixel is at the clip, 1.0 = threshold + knee (the top of the
    // Hermite ramp), so its factor is exactly the gain; the render is linear in colour (same
    // alpha and depth), so the whole ball carries 4x the light. 1e-3: f32 sums of ~200 taps.
    let (sum_plain, sum_bloom) = (ball(&plain, 11.0).iter().sum::<f32>(), ball(&bloomed, 11.0).iter().sum::<f32>());
    assert!((sum_bloom / sum_plain - 4.0).abs() < 4e-3, "ball brighter by {} (gain 4)", sum_bloom / sum_plain);
    // Below the threshold (and beyond the ball's reach) nothing changes, bit for bit.
    for y in 12..36 {
        for x in 0..16 {
            assert_eq!(bloomed.get(x, y), plain.get(x, y), "card pixel ({x}, {y})");
        }
    }
    drop(renderer);
    finish(ctx);
}

/// The renders a look takes, as progress displays count them, equal the renders it makes.
#[test]
fn render_count_is_the_number_of_renders_a_look_makes() {
    use std::cell::Cell;
    let stack = point_lights(40, 30, &[(20, 15)]);
    let lens = lens(6.0, Aperture::Disk);
    let eye = CatsEye { strength: 1.0, grid: 3 };
    let looks = [
        Character::default(),
        Character { chromatic: Some([1.0, 0.0, -1.0]), ..Character::default() },
        Character { cats_eye: Some(eye), ..Character::default() },
        Character { chromatic: Some([1.0, 0.0, -1.0]), cats_eye: Some(eye), ..Character::default() },
        // No channel differs: one render is the answer.
        Character { chromatic: Some([0.0; 3]), ..Character::default() },
    ];
    let expected = [1, 3, 9, 27, 1];
    for (look, want) in looks.iter().zip(expected) {
        let calls = Cell::new(0);
        let counting = |s: &LayerStack, _: &Lens| {
            calls.set(calls.get() + 1);
            Ok(Image::new(s.width, s.height))
        };
        look.render_prepared(&counting, &stack, &lens).unwrap();
        assert_eq!(calls.get(), want, "renders made");
        assert_eq!(look.render_count(&stack, &lens), want, "renders counted");
    }
}

/// A 128x96 two-layer frame at focus 0.5 with K = 25 (CoC ~10 px both sides of focus): a
/// front card over a textured back with highlights of 20.
fn two_layer_frame() -> LayerStack {
    let (w, h) = (128, 96);
    let front = Image::from_fn(w, h, |x, y| if (20..60).contains(&x) && (30..70).contains(&y) { [0.9, 0.3, 0.1, 1.0] } else { [0.0; 4] });
    let back = Image::from_fn(w, h, |x, y| {
        let v = ((x * 5 + y * 3) % 7) as f32 / 7.0 + if (x * 7 + y * 13) % 97 == 0 { 20.0 } else { 0.0 };
        [v, 1.0 - v.min(1.0), 0.5, 1.0]
    });
    LayerStack::new(w, h, vec![
        Layer { name: "front".into(), rgba: front, disparity: vec![0.9; w * h] },
        Layer { name: "back".into(), rgba: back, disparity: vec![0.1; w * h] },
    ])
    .unwrap()
}

/// PSNR of `a` against `b` over `b`'s peak (RGB).
fn psnr(a: &Image, b: &Image) -> f64 {
    let peak = b.pixels.iter().flat_map(|p| p[..3].iter()).fold(0.0f32, |m, &v| m.max(v)) as f64;
    let mse = a.pixels.iter().zip(&b.pixels).flat_map(|(p, q)| (0..3).map(move |c| ((p[c] - q[c]) as f64).powi(2))).sum::<f64>()
        / (3 * a.pixels.len()) as f64;
    10.0 * (peak * peak / mse).log10()
}

/// `--cats-eye` on a disk under Dr.Bokeh's default model is one render of the vignetted disk
/// (each receiver tile's cat's-eye): lens-shaped at a corner, round at the centre, and close to
/// the node grid it replaces (the grid blends four nodes' shapes, 1/3 of the frame apart).
#[test]
fn one_pass_cats_eye_is_lens_shaped_at_corners_and_close_to_the_node_grid() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let look = Character { cats_eye: Some(CatsEye::new(1.0).unwrap()), ..Character::default() };
    let (one_pass, vignetted) = look.for_method(Method::DrBokeh, &lens(6.0, Aperture::Disk));
    assert_eq!((one_pass.cats_eye, &vignetted.aperture), (None, &Aperture::vignetted(&Aperture::Disk, 1.0).unwrap()));
    for (method, base) in [
        (Method::DrBokehCompat, Aperture::Disk),
        (Method::DrBokeh, Aperture::polygon(6, 0.0, 0.3).unwrap()),
        (Method::DrBokeh, Aperture::ring(0.5).unwrap()),
    ] {
        let (kept, same) = look.for_method(method, &lens(6.0, base.clone()));
        assert_eq!((kept.cats_eye.is_some(), same.aperture), (true, base), "{method:?}: the node grid stays");
    }

    let stack = point_lights(80, 80, &[(40, 40), (8, 8)]);
    let image = render(&renderer, &stack, &vignetted).unwrap();
    let (radial, tangential) = diagonal_variances(&image, 32, 32);
    assert!((radial / tangential - 1.0).abs() < 0.05, "centre is round: {radial} vs {tangential}");
    // The corner tile's own eye (|a| ~0.45 at (8, 8)), not a blend with milder nodes inward:
    // narrower than the grid's bound of 0.7.
    let (radial, tangential) = diagonal_variances(&image, 0, 0);
    assert!(radial / tangential < 0.6, "corner is narrower radially: {radial} vs {tangential}");

    // A 128x96 two-layer frame (CoC ~10 px both sides of focus, highlights of 20) at strength
    // 0.6 against the 4x4 grid: PSNR over the peak.
    let stack = two_layer_frame();
    let base = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: Aperture::Disk };
    let eye = CatsEye { strength: 0.6, grid: 4 };
    let grid = render_cats_eye(&|s: &LayerStack, l: &Lens| render(&renderer, s, l), &stack, &base, &eye).unwrap();
    let single = render(&renderer, &stack, &Lens { aperture: Aperture::vignetted(&Aperture::Disk, 0.6).unwrap(), ..base.clone() }).unwrap();
    let disk = render(&renderer, &stack, &base).unwrap();
    // The grid's shapes at 16x16 nodes (8 px apart here), nearer a shape per receiver: the one
    // pass must be nearer it than the 4x4 grid (measured 43.4 against 40.0 dB), and near the
    // 4x4 grid (38.9 dB) where the plain disk is not (31.8 dB).
    let fine = render_cats_eye(&|s: &LayerStack, l: &Lens| render(&renderer, s, l), &stack, &base, &CatsEye { strength: 0.6, grid: 16 }).unwrap();
    let (to_fine, grid_to_fine) = (psnr(&single, &fine), psnr(&grid, &fine));
    assert!(to_fine > grid_to_fine, "one pass {to_fine} dB from the 16x16 grid, the 4x4 grid {grid_to_fine} dB");
    let (to_grid, disk_to_grid) = (psnr(&single, &grid), psnr(&disk, &grid));
    assert!(to_grid > 36.0 && disk_to_grid < to_grid - 5.0, "one pass {to_grid} dB from the 4x4 grid, the plain disk {disk_to_grid} dB");
    drop(renderer);
    finish(ctx);
}

/// `--cats-eye` on a straight-bladed polygon or the anamorphic ellipse under Dr.Bokeh's
/// default model is one render too (each receiver tile's base clipped by its vignetting disk,
/// recentred on its centroid): one render counted, and close to the 4x4 node grid of kernel
/// images it replaces on the disk test's two-layer frame (CoC ~10 px both sides of focus,
/// highlights of 20) at strength 0.6, nearer it than the plain base is.
///
/// Measured (PSNR over the grid's peak, as for the disk): polygon:6 36.7 dB from the grid (the
/// plain base 33.7), polygon:5 rotated 36.1 (33.0), anamorphic:1.8 36.3 (33.8). The grid's
/// kernel images are themselves ~35-37 dB from the gauge they sample (the base without
/// vignetting: a kernel spans the soft disk of radius r + 1/2 with bilinear edges), about the
/// size of the whole vignetting effect here (~32 dB), so a finer grid is no sharper reference
/// for these bases (a 16x16 grid is ~39 dB from the 4x4 one, ~35.6 dB from the one pass).
#[test]
fn one_pass_cats_eye_of_polygons_and_the_ellipse_is_close_to_the_node_grid() {
    let ctx = gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let stack = two_layer_frame();
    let look = Character { cats_eye: Some(CatsEye::new(0.6).unwrap()), ..Character::default() };
    for aperture in [Aperture::polygon(6, 0.0, 0.0).unwrap(), Aperture::polygon(5, 17.0, 0.0).unwrap(), Aperture::anamorphic(1.8, 0.0).unwrap()] {
        let base = Lens { coc: CocModel::new(25.0, 0.5).unwrap(), aperture: aperture.clone() };
        let (one_pass, vignetted) = look.for_method(Method::DrBokeh, &base);
        assert_eq!((one_pass.cats_eye, &vignetted.aperture), (None, &Aperture::vignetted(&aperture, 0.6).unwrap()));
        assert_eq!(one_pass.render_count(&stack, &vignetted), 1, "{aperture:?}: one render counted");
        let grid_of = |grid: usize| {
            render_cats_eye(&|s: &LayerStack, l: &Lens| render(&renderer, s, l), &stack, &base, &CatsEye { strength: 0.6, grid }).unwrap()
        };
        let grid = grid_of(4);
        let single = render(&renderer, &stack, &vignetted).unwrap();
        let plain = render(&renderer, &stack, &base).unwrap();
        let (to_grid, plain_to_grid) = (psnr(&single, &grid), psnr(&plain, &grid));
        eprintln!("{aperture:?}: one pass {to_grid:.1} dB from the 4x4 grid, the plain base {plain_to_grid:.1} dB");
        assert!(to_grid > 35.0 && to_grid > plain_to_grid + 2.0, "{aperture:?}: one pass {to_grid} dB from the 4x4 grid, the plain base {plain_to_grid} dB");
        // Without vignetting the one pass is the base's own render.
        let still = render(&renderer, &stack, &Lens { aperture: Aperture::vignetted(&aperture, 0.0).unwrap(), ..base.clone() }).unwrap();
        assert!(psnr(&still, &plain) > 120.0, "{aperture:?}: strength 0 is the base");
    }
    drop(renderer);
    finish(ctx);
}
