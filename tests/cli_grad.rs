//! `lensblur grad` end to end: gradients named after the input's channels, depth gradients
//! through the file's depth convention and camera gradients through the physical camera
//! (checked against finite differences of the render).
mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use exr::prelude::FlatSamples;
use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::render::drbokeh::{render_cpu_params, DrBokehGpu, Model, Params, Window};
use lensblur::render::Lens;
use lensblur::stack::{
    read_stack, write_image, write_stack, DepthKind, Layer, LayerStack, ReadOptions, SampleType, StackWriteOptions,
    WriteOptions,
};


/// A soft-edged subject at Z = 2 over a textured wall at Z = 4 (disparities 0.5 and 0.25).
fn stack(subject_z: f32) -> LayerStack {
    let (w, h) = (40, 32);
    let subject = Image::from_fn(w, h, |x, y| {
        let d = ((x as f32 - 18.0).powi(2) + (y as f32 - 15.0).powi(2)).sqrt();
        let a = (8.0 - d).clamp(0.0, 1.0);
        [0.9 * a, 0.4 * a, 0.1 * a, a]
    });
    let wall = Image::from_fn(w, h, |x, y| {
        let v = 0.3 + 0.2 * ((x as f32 * 0.7).sin() + (y as f32 * 0.5).cos());
        [v, 0.5 * v, 1.0 - v, 1.0]
    });
    let layers = vec![
        Layer { name: "subject".into(), rgba: subject, disparity: vec![1.0 / subject_z; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.25; w * h] },
    ];
    LayerStack::new(w, h, layers).unwrap()
}

fn grad_output(w: usize, h: usize) -> Image {
    Image::from_fn(w, h, |x, y| [((x * 3 + y) % 7) as f32 / 7.0 - 0.4, 0.3, -0.2 + (y % 3) as f32 * 0.1, 0.0])
}

fn read_channels(path: &Path) -> Vec<(String, Vec<f32>)> {
    let file = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
    file.layer_data[0].channel_data.list.iter().map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect())).collect()
}

/// L = <G, render> with the same GPU forward the backward differentiates.
fn loss(renderer: &DrBokehGpu, stack: &LayerStack, lens: &Lens, g: &Image) -> f64 {
    let image = renderer.render(stack, lens, Model::DrBokeh).unwrap();
    image.pixels.iter().zip(&g.pixels).map(|(p, q)| (0..3).map(|c| (p[c] * q[c]) as f64).sum::<f64>()).sum()
}

#[test]
fn gradients_carry_the_input_channel_names_and_the_z_chain_rule() {
    let dir = common::temp_dir("cli-grad", "names");
    let input = dir.join("shot.exr");
    write_stack(&input, &stack(2.0), &StackWriteOptions::default()).unwrap();
    let g = grad_output(40, 32);
    let g_path = dir.join("g.exr");
    write_image(&g_path, &g, &WriteOptions { sample_type: SampleType::Float, ..WriteOptions::default() }).unwrap();
    let out = dir.join("grads.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["grad", input.to_str().unwrap(), "--grad-output", g_path.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--blur", "12", "--focus-disparity", "0.25", "--json"])
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(report["camera_gradients"]["k_px"].as_f64().unwrap().is_finite());

    // Tiled: the same bytes, whatever the tile size (gradients are gathers summed in pixel order).
    let tiled_out = dir.join("grads-tiled.exr");
    let tiled = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["grad", input.to_str().unwrap(), "--grad-output", g_path.to_str().unwrap(), "-o", tiled_out.to_str().unwrap()])
        .args(["--blur", "12", "--focus-disparity", "0.25", "--json", "--tile", "16"])
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(tiled.status.success(), "{}", String::from_utf8_lossy(&tiled.stderr));
    let tiled_report: serde_json::Value = serde_json::from_slice(&tiled.stdout).unwrap();
    assert!(tiled_report["tiles"].as_u64().unwrap() > 1, "{tiled_report}");
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&tiled_out).unwrap(), "--tile 16 changed the gradients");
    assert_eq!(report["camera_gradients"], tiled_report["camera_gradients"]);

    let channels = read_channels(&out);
    let mut names: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
    names.sort();
    let expected = [
        "subject.Combined.A", "subject.Combined.B", "subject.Combined.G", "subject.Combined.R", "subject.Depth.Z",
        "wall.Combined.A", "wall.Combined.B", "wall.Combined.G", "wall.Combined.R", "wall.Depth.Z",
    ];
    assert_eq!(names, expected, "same channel names as the input");
    // The in-focus wall is not blurred, but its colour still reaches the output: non-zero.
    let wall_r = &channels.iter().find(|(n, _)| n == "wall.Combined.R").unwrap().1;
    assert!(wall_r.iter().any(|v| v.abs() > 1e-3));

    // dL/dZ of the subject at an edge pixel against a central difference of Z in the file's
    // units: the chain rule dL/dZ = dL/dd * (-1/Z^2) is what is checked. Moving the whole
    // layer (all pixels' Z) by h sums the per-pixel gradients.
    let dz = &channels.iter().find(|(n, _)| n == "subject.Depth.Z").unwrap().1;
    let analytic: f64 = dz.iter().map(|&v| v as f64).sum();
    let ctx = common::gpu();
    let renderer = DrBokehGpu::new(&ctx).unwrap();
    let lens = Lens { coc: CocModel::new(12.0, 0.25).unwrap(), aperture: Aperture::Disk };
    let h = 0.01f32;
    let numeric = (loss(&renderer, &stack(2.0 + h), &lens, &g) - loss(&renderer, &stack(2.0 - h), &lens, &g)) / (2.0 * h as f64);
    // f32 forward differences over a 0.01 step: ~1e-3 relative noise; 2% allows for the
    // curvature over the step without hiding a wrong sign or a missing 1/Z^2 factor (4x).
    assert!((analytic - numeric).abs() < 0.02 * numeric.abs(), "dL/dZ summed: analytic {analytic}, numeric {numeric}");
    assert!(numeric.abs() > 1e-2, "the check must be non-trivial: {numeric}");
    drop(renderer);
    common::finish(ctx);
}

#[test]
fn methods_without_a_backward_pass_are_refused() {
    let dir = common::temp_dir("cli-grad", "method");
    let input = dir.join("shot.exr");
    write_stack(&input, &stack(2.0), &StackWriteOptions::default()).unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["grad", input.to_str().unwrap(), "--grad-output", input.to_str().unwrap(), "-o", dir.join("g.exr").to_str().unwrap()])
        .args(["--blur", "12", "--focus-disparity", "0.25", "--method", "gather"])
        .output()
        .unwrap();
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("no backward pass"));
    assert!(!dir.join("g.exr").exists());
}

fn run_grad(input: &Path, g: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let run = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["grad", input.to_str().unwrap(), "--grad-output", g.to_str().unwrap(), "-o", out.to_str().unwrap(), "--json"])
        .args(extra)
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    serde_json::from_slice(&run.stdout).unwrap()
}

fn write_grad_output(dir: &Path) -> PathBuf {
    let path = dir.join("g.exr");
    write_image(&path, &grad_output(40, 32), &WriteOptions { sample_type: SampleType::Float, ..WriteOptions::default() }).unwrap();
    path
}

/// L = <G, render> in f64 with the CPU reference of the same forward (per-tile windows, as
/// the shaders): finite differences need steps small enough to stay between the kinks of
/// the area table (every 1/16 px of CoC), where f32 rounding would swamp them.
fn loss_f64(stack: &LayerStack, lens: &Lens, g: &Image) -> f64 {
    let params = Params::new(stack, lens, Model::DrBokeh).unwrap();
    let terms = render_cpu_params(stack, params, Window::Tiled);
    terms.composite.iter().zip(&g.pixels).map(|(o, q)| (0..3).map(|c| o[c] * q[c] as f64).sum::<f64>()).sum()
}

#[test]
fn camera_gradients_match_finite_differences_of_the_render() {
    // Focus at 3.5 m: the subject (2 m) is 3.6 px out of focus, the wall (4 m) 0.6 px, so no
    // layer sits on the |d - d_f| kink. K = 0.025 m * (50 / 3 * 40 px) = 16.7 px per 1/m.
    let camera = PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0, fstop: 1.0, focus_distance: 3.5 };
    let dir = common::temp_dir("cli-grad", "camera");
    let input = dir.join("shot.exr");
    write_stack(&input, &stack(2.0), &StackWriteOptions::default()).unwrap();
    let g_path = write_grad_output(&dir);
    let flags = ["--focal-length", "50", "--sensor-width", "3", "--fstop", "1", "--focus-distance", "3.5"];
    let report = run_grad(&input, &g_path, &dir.join("grads.exr"), &flags);
    let printed = &report["camera_gradients"];

    // The stack exactly as the command reads it (depth filled under empty pixels).
    let file = read_stack(&input, &ReadOptions::default()).unwrap();
    let g = grad_output(40, 32);
    let loss_at = |camera: &PhysicalCamera| {
        let lens = Lens { coc: CocModel::from_physical(camera, 40).unwrap(), aperture: Aperture::Disk };
        loss_f64(&file.stack, &lens, &g)
    };
    type Parameter = fn(&mut PhysicalCamera) -> &mut f32;
    let parameters: [(&str, Parameter); 3] = [
        ("focus_distance", |c| &mut c.focus_distance),
        ("fstop", |c| &mut c.fstop),
        ("focal_length_mm", |c| &mut c.focal_length_mm),
    ];
    for (name, parameter) in parameters {
        // A 1e-4 relative step: the render is strongly curved in the camera (a 1% step is 14%
        // off for the f-stop), and 1e-4 is converged to 1e-4 (measured against 1e-3 and 1e-5).
        let (mut up, mut down) = (camera, camera);
        *parameter(&mut up) *= 1.0 + 1e-4;
        *parameter(&mut down) *= 1.0 - 1e-4;
        let step = (*parameter(&mut up) - *parameter(&mut down)) as f64;
        let numeric = (loss_at(&up) - loss_at(&down)) / step;
        let analytic = printed[name].as_f64().unwrap();
        eprintln!("dL/d{name}: printed {analytic:.6e}, central difference {numeric:.6e}");
        // 0.5%: the f32 GPU backward against the f64 difference (measured 2e-4); a wrong or
        // missing chain-rule factor (-1/D^2, -K/N, 2K/f) is off by far more.
        assert!((analytic - numeric).abs() <= 5e-3 * numeric.abs(), "dL/d{name}: printed {analytic}, numeric {numeric}");
        assert!(numeric.abs() > 1e-3, "dL/d{name}: the check must be non-trivial: {numeric}");
    }
}

/// The three layers as Blender-named channels with depth stored in `kind` (as
/// `write_stack` stores it: the far value where a layer is empty), plus a pass-through channel.
fn channels_in(stack: &LayerStack, kind: DepthKind) -> Vec<(String, FlatSamples)> {
    let mut out = Vec::new();
    for layer in &stack.layers {
        for (c, name) in ["R", "G", "B", "A"].iter().enumerate() {
            out.push((format!("{}.Combined.{name}", layer.name), common::float(layer.rgba.pixels.iter().map(|p| p[c]))));
        }
        let stored = layer.rgba.pixels.iter().zip(&layer.disparity).map(|(p, &d)| kind.from_disparity(if p[3] > 0.0 { d } else { 0.0 }));
        out.push((format!("{}.Depth.Z", layer.name), common::float(stored)));
    }
    out.push(("crypto.R".into(), common::float((0..40 * 32).map(|i| (i % 5) as f32))));
    out
}

fn write_channels(path: &Path, channels: Vec<(String, FlatSamples)>) {
    common::write_single_part(path, (40, 32), channels);
}

fn named<'a>(channels: &'a [(String, Vec<f32>)], name: &str) -> &'a [f32] {
    &channels.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("no channel {name}")).1
}

#[test]
fn depth_gradients_follow_each_depth_convention_per_pixel_and_the_rest_is_zero() {
    // subject + wall as rendered; `fx`, a third layer, is left out with --layers.
    let dir = common::temp_dir("cli-grad", "kinds");
    let mut scene = stack(2.0);
    let fx = Image::from_fn(40, 32, |x, y| if x < 6 && y < 6 { [0.2, 0.9, 0.2, 1.0] } else { [0.0; 4] });
    scene.layers.push(Layer { name: "fx".into(), rgba: fx, disparity: vec![0.8; 40 * 32] });
    let g_path = write_grad_output(&dir);
    let camera = ["--blur", "12", "--focus-disparity", "0.3", "--layers", "subject,wall"];
    let mut by_kind = Vec::new();
    for kind in [DepthKind::Disparity, DepthKind::InverseZ, DepthKind::Z] {
        let input = dir.join(format!("{}.exr", kind.name()));
        write_channels(&input, channels_in(&scene, kind));
        let out = dir.join(format!("grads-{}.exr", kind.name()));
        run_grad(&input, &g_path, &out, &[&camera[..], &["--depth-kind", kind.name()]].concat());
        by_kind.push((input, read_channels(&out)));
    }
    let subject_alpha = named(&by_kind[0].1, "subject.Combined.A").len();
    assert_eq!(subject_alpha, 40 * 32);
    let alpha: Vec<f32> = scene.layers[0].rgba.pixels.iter().map(|p| p[3]).collect();
    for (input, channels) in &by_kind {
        for (name, values) in channels {
            // No influence: the pass-through channel, the unselected layer, and stored depth
            // the reader never uses (it fills depth under empty pixels from covered ones).
            let unused = name == "crypto.R" || name.starts_with("fx.");
            if unused {
                assert!(values.iter().all(|&v| v == 0.0), "{}: {name} must be exactly zero", input.display());
            }
        }
        let depth = named(channels, "subject.Depth.Z");
        assert!(depth.iter().zip(&alpha).all(|(&g, &a)| a > 0.0 || g == 0.0), "{}: empty pixels' depth", input.display());
        assert!(depth.iter().any(|&g| g.abs() > 1e-3), "{}: the subject's depth matters", input.display());
    }
    // Disparity and inverse-z store the renderer's disparity itself: d(disparity)/d(channel)
    // = 1, the same gradient file; planar Z: dL/dZ = dL/d(disparity) * (-1 / Z^2) per pixel.
    let (disparity, inverse, planar) = (&by_kind[0].1, &by_kind[1].1, &by_kind[2].1);
    assert_eq!(disparity, inverse, "disparity and inverse-z gradients");
    for layer in ["subject", "wall"] {
        let name = format!("{layer}.Depth.Z");
        let stored = read_channels(&by_kind[2].0);
        let z = named(&stored, &name);
        let (dd, dz) = (named(disparity, &name), named(planar, &name));
        let scale = dd.iter().fold(0.0f32, |m, g| m.max(g.abs()));
        for i in 0..dd.len() {
            let expected = if dd[i] == 0.0 { 0.0 } else { dd[i] * (-1.0 / (z[i] * z[i])) };
            // 1/(1/d) is 1 ulp off d, which moves the render and its gradients by ~1e-7
            // relative; 1e-5 of the largest entry is far below a wrong or missing factor.
            assert!((dz[i] - expected).abs() <= 1e-5 * scale, "{name} pixel {i}: dL/dZ {} vs {expected}", dz[i]);
        }
    }
    fd_check_per_pixel(&scene, &by_kind[0].1);
}

/// dL/d(stored disparity) of single pixels against central differences through the file:
/// the nudged file is read again (so the depth fill under empty pixels follows the nudge)
/// and rendered by the f64 reference forward.
fn fd_check_per_pixel(scene: &LayerStack, gradients: &[(String, Vec<f32>)]) {
    let lens = Lens { coc: CocModel::new(12.0, 0.3).unwrap(), aperture: Aperture::Disk };
    let g = grad_output(40, 32);
    let dir = common::temp_dir("cli-grad", "kinds-fd");
    let path = dir.join("nudged.exr");
    let options = ReadOptions { layers: Some(vec!["subject".into(), "wall".into()]), depth_kind: DepthKind::Disparity, ..ReadOptions::default() };
    let loss_with = |layer: usize, pixel: usize, h: f32| {
        let mut nudged = scene.clone();
        nudged.layers[layer].disparity[pixel] += h;
        write_channels(&path, channels_in(&nudged, DepthKind::Disparity));
        loss_f64(&read_stack(&path, &options).unwrap().stack, &lens, &g)
    };
    // The subject's soft edge (alpha 0.38 at (25, 18)), its inside next to the edge, its
    // centre, and the wall just outside the subject.
    let pixels = [(0, 18 * 40 + 25), (0, 15 * 40 + 24), (0, 15 * 40 + 18), (1, 15 * 40 + 27)];
    for (layer, pixel) in pixels {
        let name = format!("{}.Depth.Z", scene.layers[layer].name);
        // 2^-12: exact in f32 at these disparities; converged to 0.2% (a 0.01 step is 35% off
        // on the wall pixel: the render is strongly curved in depth).
        let h = 1.0 / 4096.0;
        let numeric = (loss_with(layer, pixel, h) - loss_with(layer, pixel, -h)) / (2.0 * h as f64);
        let analytic = named(gradients, &name)[pixel] as f64;
        eprintln!("{name} pixel {pixel}: printed {analytic:.6e}, central difference {numeric:.6e}");
        // 1% + 1e-3: the step's curvature and the f32 depth fill's rounding (~1e-4 absolute
        // in the quotient); a gradient that ignored the fill or the alpha is off by far more.
        assert!((analytic - numeric).abs() <= 0.01 * numeric.abs() + 1e-3, "{name} pixel {pixel}: {analytic} vs {numeric}");
    }
}

/// `--max-memory` caps the backward as it caps `render`: a cap the frame's own input and
/// output exceed is refused before any file appears, and a cap it fits gives the same bytes.
#[test]
fn max_memory_caps_the_backward() {
    let dir = common::temp_dir("cli-grad", "max-memory");
    let input = dir.join("shot.exr");
    write_stack(&input, &stack(2.0), &StackWriteOptions::default()).unwrap();
    let g = write_grad_output(&dir);
    let camera = ["--blur", "12", "--focus-disparity", "0.25"];
    let (free, capped) = (dir.join("free.exr"), dir.join("capped.exr"));
    run_grad(&input, &g, &free, &camera);
    run_grad(&input, &g, &capped, &[&camera[..], &["--max-memory", "256M"]].concat());
    assert_eq!(std::fs::read(&free).unwrap(), std::fs::read(&capped).unwrap(), "a cap the frame fits changes nothing");
    let refused = dir.join("refused.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["grad", input.to_str().unwrap(), "--grad-output", g.to_str().unwrap(), "-o", refused.to_str().unwrap()])
        .args(camera)
        .args(["--max-memory", "1K"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && stderr.contains("--max-memory") && stderr.contains("is less than"), "{stderr}");
    assert!(!refused.exists());
}
