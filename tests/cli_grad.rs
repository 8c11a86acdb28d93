//! `lensblur grad` end to end: gradients named after the input's channels, depth gradients
//! through the file's Z convention (checked against finite differences of the render).
mod common;

use std::path::Path;
use std::process::Command;

use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::Lens;
use lensblur::stack::{write_image, write_stack, Layer, LayerStack, SampleType, StackWriteOptions, WriteOptions};


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
