//! `lensblur fit-depth` end to end: from a wrong depth, the fitted depth moves toward the
//! depth that produced the target, colour channels pass through unchanged.
mod common;

use std::path::Path;
use std::process::Command;

use lensblur::camera::{Aperture, CocModel};
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
