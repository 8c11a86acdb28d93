//! Properties of the thin-lens ground-truth tracer that the whole benchmark rests on.
use std::sync::Arc;

use lensblur::camera::{CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::raytrace::texture::{Rgba, Texture};
use lensblur::raytrace::{builtin_scenes, render_ground_truth, Scene, Surface, TraceOptions, EMPTY_DEPTH};

/// 200 mm f/2 on a 36 mm sensor: K = 0.05 m * (200/36) * W px per unit disparity.
fn tele(focus_distance: f32) -> PhysicalCamera {
    PhysicalCamera { focal_length_mm: 200.0, sensor_width_mm: 36.0, fstop: 2.0, focus_distance }
}

fn one_plane(camera: PhysicalCamera, z: f32, size: usize, texture: Arc<dyn Texture>) -> Scene {
    let surfaces = vec![Surface::billboard("plane", z, &camera, texture)];
    Scene { name: "test".into(), description: String::new(), camera, width: size, height: size, surfaces, z_pass: Default::default() }
}

fn options(samples_per_axis: usize) -> TraceOptions {
    TraceOptions { samples_per_axis, max_rounds: 1, ..TraceOptions::default() }
}

/// Smooth opaque texture: sinusoids of period 1 texture unit (half the frame width).
#[derive(Debug)]
struct Waves;
impl Texture for Waves {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        let tau = std::f32::consts::TAU;
        let c = 0.5 + 0.2 * (tau * u).sin() + 0.2 * (tau * v).cos();
        [c, 1.0 - c, 0.5, 1.0]
    }
}

/// Black, opaque everywhere, with one bright disc of `radius` texture units at the centre.
#[derive(Debug)]
struct Dot {
    radius: f32,
}
impl Texture for Dot {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        let c = if u * u + v * v <= self.radius * self.radius { 1.0 } else { 0.0 };
        [c, c, c, 1.0]
    }
}

fn luminance_sum(image: &Image) -> f64 {
    image.pixels.iter().map(|p| p[0] as f64).sum()
}

/// Luminance-weighted `E[r^2]` about the weighted centroid.
fn second_moment(image: &Image) -> f64 {
    let total = luminance_sum(image);
    let (mut cx, mut cy) = (0.0, 0.0);
    for y in 0..image.height {
        for x in 0..image.width {
            let w = image.get(x, y)[0] as f64 / total;
            (cx, cy) = (cx + w * (x as f64 + 0.5), cy + w * (y as f64 + 0.5));
        }
    }
    let mut m = 0.0;
    for y in 0..image.height {
        for x in 0..image.width {
            let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
            m += image.get(x, y)[0] as f64 / total * (dx * dx + dy * dy);
        }
    }
    m
}

#[test]
fn in_focus_plane_reproduces_its_texture() {
    let size = 64;
    let scene = one_plane(tele(3.0), 3.0, size, Arc::new(Waves));
    let truth = render_ground_truth(&scene, &options(8)).unwrap();
    // Waves has a period of 32 px here; box filtering damps each sinusoid by
    // 1 - sinc(pi/32) = 1.6e-3 of its 0.2 amplitude, so 2e-3 bounds filter + sampling error.
    let mut worst: f32 = 0.0;
    for y in 0..size {
        for x in 0..size {
            let (u, v) = ((x as f32 + 0.5) * 2.0 / size as f32 - 1.0, (y as f32 + 0.5) * 2.0 / size as f32 - 1.0);
            let expected = Waves.sample(u, v);
            let got = truth.defocused.get(x, y);
            worst = worst.max((0..4).map(|c| (got[c] - expected[c]).abs()).fold(0.0, f32::max));
            // The focus plane is hit at the same point by every lens ray: only rounding differs.
            let pinhole = truth.pinhole.get(x, y);
            assert!((0..4).all(|c| (got[c] - pinhole[c]).abs() < 1e-5), "({x},{y}) {got:?} vs {pinhole:?}");
        }
    }
    eprintln!("in-focus plane: largest deviation {worst}");
    assert!(worst < 2e-3, "largest deviation from the texture {worst}");
}

/// Renders the centred dot on a plane at `z` (focus 1 m) and checks the spread radius.
fn check_coc_radius(z: f32) {
    let size = 64;
    let camera = tele(1.0);
    let k = camera.aperture_radius() * camera.focal_length_px(size);
    let predicted = (k * (1.0 / z - 1.0)).abs() as f64;
    // Dot radius: 4 px of the pinhole image (1 px = 2 / size texture units). A smaller dot
    // is seen through too few lens strata per pixel and the estimate gets noisy (~3%).
    let scene = one_plane(camera, z, size, Arc::new(Dot { radius: 8.0 / size as f32 }));
    let truth = render_ground_truth(&scene, &options(16)).unwrap();
    // Defocus convolves the pinhole image with a uniform disc of radius R, whose E[r^2] is
    // R^2 / 2; second moments of convolved distributions add.
    let measured = (2.0 * (second_moment(&truth.defocused) - second_moment(&truth.pinhole))).sqrt();
    eprintln!("z = {z}: CoC radius measured {measured:.3} px, predicted {predicted:.3} px");
    assert!((measured / predicted - 1.0).abs() < 0.03, "z = {z}: measured {measured:.3} px, predicted {predicted:.3} px");
    // A uniform disc, not a Gaussian of the same variance: where the dot's whole spread
    // overlaps (r < R - 4 px) the image is flat at energy / (pi R^2); a Gaussian would peak
    // at twice that. Mean over the central 6 x 6 px; 10% covers the lens sampling noise.
    let total = luminance_sum(&truth.defocused);
    let centre: f64 = (29..35).flat_map(|y| (29..35).map(move |x| (x, y))).map(|(x, y)| truth.defocused.get(x, y)[0] as f64).sum::<f64>() / 36.0;
    let plateau = total / (std::f64::consts::PI * predicted * predicted);
    eprintln!("z = {z}: centre {centre:.5}, uniform-disc plateau {plateau:.5}");
    assert!((centre / plateau - 1.0).abs() < 0.1, "z = {z}: centre {centre}, plateau of a uniform disc {plateau}");
}

#[test]
fn point_behind_focus_spreads_to_predicted_coc_radius() {
    check_coc_radius(2.0); // R = K / 2 = 8.9 px
}

#[test]
fn point_in_front_of_focus_spreads_to_predicted_coc_radius() {
    check_coc_radius(0.5); // R = K = 17.8 px
}

#[test]
fn defocus_conserves_energy() {
    // The spread dot stays inside the frame (17.8 + 10 px < 32 px), so nothing leaves it. A
    // 10 px dot is seen through ~30% of the lens from each pixel, so the lens sampling noise
    // of the sum is ~0.1%; 0.5% is a 5-sigma bound.
    let size = 64;
    let scene = one_plane(tele(1.0), 0.5, size, Arc::new(Dot { radius: 20.0 / size as f32 }));
    let truth = render_ground_truth(&scene, &options(16)).unwrap();
    let (before, after) = (luminance_sum(&truth.pinhole), luminance_sum(&truth.defocused));
    eprintln!("energy ratio defocused / pinhole = {}", after / before);
    assert!((after / before - 1.0).abs() < 0.005, "pinhole {before}, defocused {after}");
}

#[test]
fn layers_composited_over_equal_the_pinhole_image() {
    for scene in builtin_scenes() {
        let truth = render_ground_truth(&scene, &TraceOptions { scale: 0.25, ..options(4) }).unwrap();
        let mut total_error = 0.0f64;
        for (i, pinhole) in truth.pinhole.pixels.iter().enumerate() {
            let mut acc = [0.0f32; 4];
            for layer in &truth.layers.layers {
                let c = layer.rgba.pixels[i];
                for k in 0..4 {
                    acc[k] += (1.0 - acc[3]) * c[k];
                }
            }
            // Compare in clipped display range: HDR lights behind a cut-out edge would
            // otherwise dominate the mean with a single pixel.
            total_error += (0..4).map(|k| (acc[k].min(1.0) - pinhole[k].min(1.0)).abs() as f64).sum::<f64>() / 4.0;
        }
        let mean = total_error / truth.pinhole.pixels.len() as f64;
        // Over of box-filtered layers differs from box-filtered over only where a cut-out
        // edge and the content behind it vary inside one pixel: a small mean difference.
        eprintln!("{}: mean |over(layers) - pinhole| = {mean:.2e}", scene.name);
        assert!(mean < 5e-3, "{}: mean |over(layers) - pinhole| = {mean}", scene.name);
    }
}

#[test]
fn renders_are_deterministic_and_seeded() {
    let scene = lensblur::raytrace::builtin_scene("fairy-lights").unwrap();
    let opts = TraceOptions { scale: 0.25, max_rounds: 3, ..options(4) };
    let a = render_ground_truth(&scene, &opts).unwrap();
    let b = render_ground_truth(&scene, &opts).unwrap();
    assert_eq!(a.defocused, b.defocused);
    assert_eq!(a.layers, b.layers);
    let c = render_ground_truth(&scene, &TraceOptions { seed: 1, ..opts }).unwrap();
    assert_ne!(a.defocused, c.defocused, "the seed must change the sample pattern");
}

#[test]
fn pinhole_depth_is_the_first_opaque_surface_or_empty() {
    #[derive(Debug)]
    struct Disc;
    impl Texture for Disc {
        fn sample(&self, u: f32, v: f32) -> Rgba {
            if u * u + v * v < 0.25 { [0.5, 0.5, 0.5, 1.0] } else { [0.0; 4] }
        }
    }
    let size = 32;
    let scene = one_plane(tele(1.0), 2.5, size, Arc::new(Disc));
    let truth = render_ground_truth(&scene, &options(2)).unwrap();
    let depth = |x: usize, y: usize| truth.pinhole_depth[y * size + x];
    assert!((depth(16, 16) - 2.5).abs() < 1e-4, "centre pixel sees the disc at 2.5 m");
    assert_eq!(depth(0, 0), EMPTY_DEPTH, "corner pixel sees nothing");
    assert_eq!(truth.layers.layers[0].disparity[0], 0.4, "layer disparity defined where empty");
}

#[test]
fn builtin_scenes_cover_the_benchmark_design() {
    let scenes = builtin_scenes();
    assert!((6..=10).contains(&scenes.len()));
    let mut max_cocs = Vec::new();
    for scene in &scenes {
        assert!((2..=5).contains(&scene.surfaces.len()), "{} has {} layers", scene.name, scene.surfaces.len());
        let (w, h) = (scene.width, scene.height);
        max_cocs.push(scene.coc_range_px(w, h).unwrap().1);
        let focus = 1.0 / scene.camera.focus_distance;
        assert!(scene.surfaces.iter().any(|s| (1.0 / s.z0 - focus).abs() < 1e-3), "{}: something is in focus", scene.name);
    }
    let (lo, hi) = max_cocs.iter().fold((f32::INFINITY, 0.0f32), |(a, b), &r| (a.min(r), b.max(r)));
    assert!(lo <= 4.0 && hi >= 35.0 && hi <= 45.0, "largest CoC per scene spans {lo}..{hi} px");
    assert!(scenes.iter().any(|s| s.surfaces.iter().any(|p| p.slope != [0.0, 0.0])), "a tilted plane");
    let focus_on = |back: bool| {
        scenes.iter().any(|s| {
            let target = if back { s.surfaces.last() } else { s.surfaces.first() };
            target.is_some_and(|p| (p.z0 - s.camera.focus_distance).abs() < 1e-3)
        })
    };
    assert!(focus_on(true) && focus_on(false), "both background-focus and foreground-focus scenes");
}

#[test]
fn layers_exr_uses_blender_channel_names() {
    let scene = lensblur::raytrace::builtin_scene("portrait-night").unwrap();
    let truth = render_ground_truth(&scene, &TraceOptions { scale: 0.125, ..options(1) }).unwrap();
    let dir = std::env::temp_dir().join(format!("lensblur-raytrace-test-{}", std::process::id()));
    lensblur::raytrace::output::write_ground_truth(&truth, &dir).unwrap();
    let image = exr::prelude::read_all_flat_layers_from_file(dir.join("layers.exr")).unwrap();
    let names: Vec<String> = image.layer_data[0].channel_data.list.iter().map(|c| c.name.to_string()).collect();
    for expected in ["subject.Combined.R", "subject.Combined.A", "subject.Depth.Z", "background.Depth.Z"] {
        assert!(names.iter().any(|n| n == expected), "{expected} missing from {names:?}");
    }
    assert!(dir.join("camera.json").exists() && dir.join("defocused.png").exists());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn single_image_scenes_are_square_and_match_their_coc_table() {
    // The table in `single_image_scenes`' documentation, CoC radius per plane at 256^2.
    let table: [(&str, &[f32]); 3] =
        [("silhouette-hdr", &[0.0, 10.7]), ("five-planes", &[6.9, 0.0, 4.4, 6.9, 9.9]), ("thin-near", &[17.1, 0.0, 3.0])];
    let scenes = lensblur::raytrace::single_image_scenes();
    assert_eq!(scenes.len(), table.len());
    for (scene, (name, radii)) in scenes.iter().zip(table) {
        assert_eq!((scene.name.as_str(), scene.width, scene.height), (name, 256, 256));
        let coc = CocModel::from_physical(&scene.camera, 256).unwrap();
        let got: Vec<f32> = scene.surfaces.iter().map(|s| coc.radius(1.0 / s.z0)).collect();
        assert_eq!(got.len(), radii.len(), "{name}");
        for (g, r) in got.iter().zip(radii) {
            assert!((g - r).abs() < 0.05, "{name}: CoC {got:?} px, table {radii:?}");
        }
        assert!(lensblur::raytrace::builtin_scene(name).is_ok(), "{name} found by name");
    }
}

/// Opaque left of `u = edge`, transparent right of it.
#[derive(Debug)]
struct HalfPlane {
    edge: f32,
}
impl Texture for HalfPlane {
    fn sample(&self, u: f32, _: f32) -> Rgba {
        if u < self.edge {
            [1.0, 0.0, 0.0, 1.0]
        } else {
            [0.0; 4]
        }
    }
}

#[test]
fn a_one_sample_z_pass_jitters_depth_edges_only() {
    // A half plane at 2 m over a wall at 10 m whose edge covers 80% of pixel column 16. The
    // pixel-centre Z pass gives that column the front; Cycles' one jittered sample per pixel
    // gives a fifth of its rows the wall, and agrees everywhere else.
    let camera = tele(4.0);
    let mut scene = one_plane(camera, 10.0, 32, Arc::new(Waves));
    scene.surfaces.insert(0, Surface::billboard("front", 2.0, &camera, Arc::new(HalfPlane { edge: 0.05 })));
    let centre = render_ground_truth(&scene, &options(4)).unwrap();
    scene.z_pass = lensblur::raytrace::ZPass::OneSample;
    let jittered = render_ground_truth(&scene, &options(4)).unwrap();
    let front = |z: f32| z < 5.0;
    let (mut differ, w) = (0, 32);
    for i in 0..w * w {
        let (a, b) = (front(centre.pinhole_depth[i]), front(jittered.pinhole_depth[i]));
        if a != b {
            differ += 1;
            let x = i % w;
            let row: Vec<bool> = (0..w).map(|x| front(centre.pinhole_depth[i / w * w + x])).collect();
            let edge = row.iter().position(|&f| !f).unwrap_or(w);
            assert!(x + 1 >= edge && x <= edge, "pixel {i} is a pixel from the edge at {edge}");
        }
    }
    assert!(differ > 0, "some edge pixels take the other side's depth");
    assert_eq!(centre.pinhole.pixels, jittered.pinhole.pixels, "colour does not change");
}

#[test]
fn only_single_image_scenes_use_the_jittered_z_pass_and_other_cache_keys_stay() {
    use lensblur::raytrace::ZPass;
    for scene in builtin_scenes() {
        assert_eq!(scene.z_pass, ZPass::PixelCentre, "{}", scene.name);
        // The ground-truth cache keys hash the Debug text: the default leaves it as it was.
        assert!(!format!("{scene:?}").contains("z_pass"), "{}", scene.name);
    }
    for scene in lensblur::raytrace::single_image_scenes() {
        assert_eq!(scene.z_pass, ZPass::OneSample, "{}", scene.name);
        assert!(format!("{scene:?}").contains("OneSample"), "{}", scene.name);
    }
}
