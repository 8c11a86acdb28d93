//! `lensblur fit-depth` end to end: from a wrong depth, the fitted depth moves toward the
//! depth that produced the target; OUT is the input with only the depth samples of covered
//! pixels changed; with a layer's depth held fixed, a wrong focus moves toward the truth.
mod common;

use std::path::Path;
use std::process::Command;

use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::{FlatSamples, LayerAttributes};
use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::Lens;
use lensblur::stack::{write_image, write_stack, Layer, LayerStack, SampleType, StackWriteOptions, WriteOptions};


/// A textured disk at depth `subject_z` over a textured wall at Z = 4 (in focus).
fn stack(subject_z: f32) -> LayerStack {
    let (w, h) = (48, 40);
    let subject = Image::from_fn(w, h, |x, y| {
        let d = ((x as f32 - 22.0).powi(2) + (y as f32 - 19.0).powi(2)).sqrt();
        let a = (10.0 - d).clamp(0.0, 1.0);
        let v = 0.5 + 0.4 * ((x as f32 * 0.9).sin() * (y as f32 * 0.7).cos());
        [v * a, 0.3 * a, (1.0 - v) * a, a]
    });
    let wall = Image::from_fn(w, h, |x, y| {
        let v = if (x / 3 + y / 3) % 2 == 0 { 0.8 } else { 0.15 };
        [v, v, 0.5, 1.0]
    });
    let layers = vec![
        Layer { name: "subject".into(), rgba: subject, disparity: vec![1.0 / subject_z; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.25; w * h] },
    ];
    LayerStack::new(w, h, layers).unwrap()
}

fn channel(path: &Path, name: &str) -> Vec<f32> {
    let file = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
    let c = file.layer_data[0].channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
    c.sample_data.values_as_f32().collect()
}

/// Mean |1/Z - 1/z_true| over the subject's covered pixels.
fn disparity_error(z: &[f32], alpha: &[f32], truth: f32) -> f32 {
    let covered: Vec<f32> = z.iter().zip(alpha).filter(|(_, &a)| a > 0.5).map(|(&z, _)| (1.0 / z - 1.0 / truth).abs()).collect();
    covered.iter().sum::<f32>() / covered.len() as f32
}

#[test]
fn fitted_depth_approaches_the_depth_that_made_the_target() {
    let dir = common::temp_dir("cli-fit", "fit");
    let ctx = common::gpu();
    let lens = Lens { coc: CocModel::new(16.0, 0.25).unwrap(), aperture: Aperture::Disk };
    // Target: the subject at Z = 2 (disparity 0.5, CoC 4 px), rendered by Dr.Bokeh itself.
    let target = DrBokehGpu::new(&ctx).unwrap().render(&stack(2.0), &lens, Model::DrBokeh).unwrap();
    common::finish(ctx);
    let target_path = dir.join("target.exr");
    write_image(&target_path, &target, &WriteOptions { sample_type: SampleType::Float, ..WriteOptions::default() }).unwrap();
    // Start: the subject at Z = 3 (disparity 0.333, CoC 1.3 px).
    let input = dir.join("start.exr");
    write_stack(&input, &stack(3.0), &StackWriteOptions::default()).unwrap();
    let out = dir.join("fitted.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["fit-depth", input.to_str().unwrap(), "--target", target_path.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--blur", "16", "--focus-disparity", "0.25", "--iters", "100", "--json"])
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let (first, best) = (report["loss_first"].as_f64().unwrap(), report["loss_best"].as_f64().unwrap());
    assert!(best < 0.5 * first, "loss {first} -> {best}");

    let alpha = channel(&out, "subject.Combined.A");
    let before = disparity_error(&channel(&input, "subject.Depth.Z"), &alpha, 2.0);
    let after = disparity_error(&channel(&out, "subject.Depth.Z"), &alpha, 2.0);
    // 0.167 at the start; the subject's blur pins its depth (the wall is in focus, so the
    // front/behind-focus mirror is 0.0, far from the start): a 3x reduction is asserted.
    assert!(after < before / 3.0, "disparity error {before} -> {after}");
    assert_eq!(channel(&out, "wall.Combined.R"), channel(&input, "wall.Combined.R"), "colour passes through");
}

fn fit_depth(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lensblur")).arg("fit-depth").args(args).env("LENSBLUR_VALIDATION", "1").output().unwrap()
}

/// A multi-part stack as a compositor might hand it over: display window 24x20 at (2, -1),
/// part `subject` (a soft disk) with half colour, half depth and an 18x16 data window at
/// (5, 1), part `wall` with float depth and a half pass-through channel, camera attributes
/// in the header. Depth where the subject is empty is 7.5 (not the far value), so keeping it
/// shows.
fn write_compositor_stack(path: &Path) {
    let (w, h, sw, sh) = (24, 20, 18, 16);
    let texture = |i: usize, c: usize| 0.2 + 0.15 * c as f32 + 0.3 * ((i * 7 + c) % 5) as f32 / 5.0;
    // Subject samples are at display pixel (3 + col, 2 + row).
    let alpha: Vec<f32> = (0..sw * sh)
        .map(|i| (6.5 - ((3 + i % sw) as f32 - 12.0).hypot((2 + i / sw) as f32 - 10.0)).clamp(0.0, 1.0))
        .collect();
    let mut subject: Vec<(String, FlatSamples)> = ["R", "G", "B"]
        .iter()
        .enumerate()
        .map(|(c, n)| (n.to_string(), common::half((0..sw * sh).map(|i| texture(i, c) * alpha[i]))))
        .collect();
    subject.push(("A".into(), common::half(alpha.iter().copied())));
    subject.push(("Z".into(), common::half(alpha.iter().map(|&a| if a > 0.0 { 3.0 } else { 7.5 }))));
    let checker = |i: usize| if (i % w / 3 + i / w / 3) % 2 == 0 { 0.8 } else { 0.15 };
    let wall: Vec<(String, FlatSamples)> = vec![
        ("R".into(), common::half((0..w * h).map(checker))),
        ("G".into(), common::half((0..w * h).map(checker))),
        ("B".into(), common::half((0..w * h).map(|_| 0.5))),
        ("A".into(), common::half((0..w * h).map(|_| 1.0))),
        ("Z".into(), common::float((0..w * h).map(|_| 4.0))),
        ("crypto.R".into(), common::half((0..w * h).map(|i| (i % 13) as f32 * 0.25))),
    ];
    let mut own = LayerAttributes { focus: Some(4.0), aperture: Some(1.0), ..LayerAttributes::default() };
    own.other.insert(Text::from("effectiveFocalLength"), AttributeValue::F32(50.0));
    let parts = vec![
        common::Part { name: Some("subject"), origin: (5, 1), size: (sw, sh), channels: subject },
        common::Part { name: Some("wall"), origin: (2, -1), size: (w, h), channels: wall },
    ];
    common::write_parts_with(path, ((2, -1), (w, h)), own, parts);
}

type ExrFile = exr::image::Image<exr::image::Layers<exr::image::AnyChannels<FlatSamples>>>;

fn read_all(path: &Path) -> ExrFile {
    exr::prelude::read_all_flat_layers_from_file(path).unwrap()
}

/// The raw bits of a channel's samples (so half stays half and equality is byte-for-byte).
fn bits(samples: &FlatSamples) -> Vec<u32> {
    match samples {
        FlatSamples::F16(v) => v.iter().map(|s| s.to_bits() as u32).collect(),
        FlatSamples::F32(v) => v.iter().map(|s| s.to_bits()).collect(),
        FlatSamples::U32(v) => v.clone(),
    }
}

#[test]
fn output_is_the_input_with_only_covered_depth_samples_changed() {
    let dir = common::temp_dir("cli-fit", "keep");
    let (input, target, out) = (dir.join("shot.exr"), dir.join("target.exr"), dir.join("fitted.exr"));
    write_compositor_stack(&input);
    // A flat grey target: the fit blurs both layers (CoC 2.4 and 3.7 px at the start) more.
    write_image(&target, &Image::filled(24, 20, [0.4, 0.4, 0.4, 1.0]), &WriteOptions::default()).unwrap();
    let run = fit_depth(&[
        input.to_str().unwrap(),
        "--target",
        target.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--blur",
        "16",
        "--focus-disparity",
        "0.1",
        "--iters",
        "3",
        "--renderer",
        "gausspsf",
    ]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));

    let (before, after) = (read_all(&input), read_all(&out));
    assert_eq!(after.attributes.display_window, before.attributes.display_window);
    assert_eq!(after.layer_data.len(), 2);
    for (old, new) in before.layer_data.iter().zip(&after.layer_data) {
        let name = old.attributes.layer_name.as_ref().map(|t| t.to_string()).unwrap_or_default();
        assert_eq!(new.attributes, old.attributes, "part '{name}': name, data window and camera attributes kept");
        assert_eq!(new.encoding, old.encoding, "part '{name}'");
        let channels = old.channel_data.list.iter().zip(&new.channel_data.list);
        for (a, b) in channels {
            let sample_type = |c: &exr::image::AnyChannel<FlatSamples>| std::mem::discriminant(&c.sample_data);
            assert_eq!((&a.name, sample_type(a)), (&b.name, sample_type(b)), "part '{name}': names and sample types kept");
            let (a_bits, b_bits) = (bits(&a.sample_data), bits(&b.sample_data));
            if a.name.to_string() != "Z" {
                assert_eq!(a_bits, b_bits, "part '{name}' channel '{}' is byte-for-byte the input's", a.name);
                continue;
            }
            let alpha = old.channel_data.list.iter().find(|c| c.name.to_string() == "A").unwrap();
            let alpha: Vec<f32> = alpha.sample_data.values_as_f32().collect();
            let changed = a_bits.iter().zip(&b_bits).zip(&alpha).filter(|((x, y), _)| x != y);
            assert!(changed.clone().all(|(_, &a)| a > 0.0), "part '{name}': depth of empty pixels is kept");
            assert!(changed.count() > alpha.iter().filter(|&&a| a > 0.0).count() / 2, "part '{name}': the fit moved the covered depth");
        }
    }
}

/// The physical camera of the focus test: K = 0.025 m * (50 / 3 * 48 px) = 20 px per 1/m.
const CAMERA: PhysicalCamera = PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0, fstop: 1.0, focus_distance: 4.0 };

#[test]
fn fitted_focus_moves_toward_the_truth_when_a_layer_depth_is_fixed() {
    // Truth: subject at 2 m, wall at 4 m, focus on the wall (4 m). Start: subject at 3 m and
    // the focus at 3 m; the wall's depth is known (--fixed-layers), which pins the focus.
    let dir = common::temp_dir("cli-fit", "focus");
    let ctx = common::gpu();
    let truth_lens = Lens { coc: CocModel::from_physical(&CAMERA, 48).unwrap(), aperture: Aperture::Disk };
    let target = DrBokehGpu::new(&ctx).unwrap().render(&stack(2.0), &truth_lens, Model::DrBokeh).unwrap();
    common::finish(ctx);
    let target_path = dir.join("target.exr");
    write_image(&target_path, &target, &WriteOptions { sample_type: SampleType::Float, ..WriteOptions::default() }).unwrap();
    let (input, out) = (dir.join("start.exr"), dir.join("fitted.exr"));
    write_stack(&input, &stack(3.0), &StackWriteOptions::default()).unwrap();
    let camera = ["--focal-length", "50", "--sensor-width", "3", "--fstop", "1", "--focus-distance", "3"];
    let run = fit_depth(
        &[
            &[input.to_str().unwrap(), "--target", target_path.to_str().unwrap(), "-o", out.to_str().unwrap()][..],
            &camera,
            &["--fit-focus", "--fixed-layers", "wa*", "--iters", "60", "--json"],
        ]
        .concat(),
    );
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let (distance, disparity) = (report["focus_distance"].as_f64().unwrap(), report["focus_disparity"].as_f64().unwrap());
    assert!((distance * disparity - 1.0).abs() < 1e-6, "distance is 1 / disparity: {report}");
    // Start 1/3 - 1/4 = 0.083 off in disparity: at least 3/4 of that must go (measured
    // 0.083 -> 0.008, focus 3 m -> 4.14 m; the bound leaves room for other devices' rounding).
    let (before, after) = (1.0 / 3.0 - 0.25, (disparity - 0.25).abs());
    eprintln!("focus disparity error {before:.4} -> {after:.4} (distance {distance:.3} m)");
    assert!(after < 0.25 * before, "focus disparity error {before} -> {after}: {report}");

    let header = exr::meta::MetaData::read_from_file(&out, false).unwrap();
    let stamped = header.headers[0].own_attributes.focus.unwrap();
    assert_eq!(stamped, distance as f32, "the fitted focus is stamped into the header");
    assert_eq!(channel(&out, "wall.Depth.Z"), channel(&input, "wall.Depth.Z"), "the fixed layer keeps its depth");

    // Without --json the fitted focus is printed, as a distance and as a disparity.
    let text = fit_depth(
        &[
            &[input.to_str().unwrap(), "--target", target_path.to_str().unwrap(), "-o", out.to_str().unwrap()][..],
            &camera,
            &["--fit-focus", "--fixed-layers", "wall", "--iters", "1", "--renderer", "gausspsf"],
        ]
        .concat(),
    );
    let stdout = String::from_utf8_lossy(&text.stdout);
    assert!(text.status.success() && stdout.contains("fitted focus: distance") && stdout.contains("disparity"), "{stdout}");
}


/// `--renderer` is a registry method: one without a backward pass is refused before any work
/// (the files are not even read), naming those that have one (GaussPSF among them), and an
/// unknown name lists the methods.
#[test]
fn renderers_are_the_registered_methods_with_a_backward_pass() {
    let dir = common::temp_dir("cli-fit", "renderer");
    let (input, target, out) = (dir.join("missing.exr"), dir.join("target.exr"), dir.join("fitted.exr"));
    let paths = [input.to_str().unwrap(), "--target", target.to_str().unwrap(), "-o", out.to_str().unwrap()];
    let refused = |renderer: &str| {
        let run = fit_depth(&[&paths[..], &["--blur", "16", "--focus-disparity", "0.1", "--renderer", renderer]].concat());
        assert!(!run.status.success() && !out.exists());
        String::from_utf8_lossy(&run.stderr).into_owned()
    };
    let stderr = refused("gather");
    assert!(stderr.contains("method 'gather' has no backward pass; use drbokeh or drbokeh-compat or gausspsf"), "{stderr}");
    let stderr = refused("nope");
    assert!(stderr.contains("unknown method 'nope' (available: drbokeh,"), "{stderr}");
}
