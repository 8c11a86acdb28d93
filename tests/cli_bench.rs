//! `lensblur raytrace` and `lensblur bench` through the binary: the ground-truth files a user
//! gets, the benchmark's table, JSON report and contact sheet on a real ray-traced scene, and
//! the CPU-only benchmark on a machine without Vulkan.
mod common;
use std::path::Path;

use lensblur::stack::{read_stack, ReadOptions};

fn run_ok(args: &[&str], env: &[(&str, &str)]) -> (String, String) {
    let output = common::lensblur(args, env);
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout).into_owned(), String::from_utf8_lossy(&output.stderr).into_owned());
    assert!(output.status.success(), "{args:?} failed: {stderr}");
    (stdout, stderr)
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn raytrace_writes_the_pinhole_image_true_layers_defocus_and_camera() {
    let dir = common::temp_dir("cli-bench", "raytrace");
    let out = dir.join("small");
    // A quarter of the native 256x192 and one round of 2x2 rays: the files, not the noise.
    let args = ["raytrace", "small-coc", "-o", path(&out), "--scale", "0.25", "--samples", "2", "--min-rounds", "1", "--max-rounds", "1"];
    run_ok(&args, &[]);
    for file in ["pinhole.exr", "layers.exr", "defocused.exr", "camera.json", "pinhole.png", "defocused.png"] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    let layers = read_stack(&out.join("layers.exr"), &ReadOptions::default()).expect("layers.exr reads back as a stack");
    assert_eq!((layers.stack.width, layers.stack.height), (64, 48));
    assert_eq!(layers.stack.layers.len(), 3, "small-coc has three billboards");
    let camera: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("camera.json")).unwrap()).unwrap();
    for key in ["focal_length_mm", "sensor_width_mm", "fstop", "focus_distance"] {
        let value = camera["camera"][key].as_f64();
        assert!(value.is_some_and(|v| v > 0.0), "camera.json lacks a positive camera.{key}: {camera}");
    }
}

#[test]
fn bench_prints_the_table_writes_json_sheet_and_renders_and_runs_without_vulkan() {
    let dir = common::temp_dir("cli-bench", "bench");
    let (cache, json, sheet, renders) = (dir.join("cache"), dir.join("bench.json"), dir.join("sheet.png"), dir.join("renders"));
    let common = ["bench", "quality", "--quick", "--scenes", "small-coc", "--cache", path(&cache)];
    let mut args = common.to_vec();
    args.extend(["--methods", "oracle,drbokeh,gather", "--json", path(&json), "--sheet", path(&sheet), "--renders", path(&renders)]);
    let (table, _) = run_ok(&args, &[]);
    for row in ["oracle ", "drbokeh ", "gather ", "PSNR dB", "mean over 1 scene(s) (small-coc)"] {
        assert!(table.contains(row), "'{row}' missing from the table:\n{table}");
    }
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let psnr = |name: &str| -> f64 {
        let methods = report["methods"].as_array().expect("methods array");
        let method = methods.iter().find(|m| m["name"] == name).unwrap_or_else(|| panic!("{name} not in the report"));
        method["mean"]["psnr"].as_f64().expect("numeric PSNR")
    };
    // Measured on this scene: oracle 42.7 dB, drbokeh 41.6 dB, gather 25.6 dB. The layered
    // methods must stay far ahead of the single-image baseline and near each other.
    let (oracle, drbokeh, gather) = (psnr("oracle"), psnr("drbokeh"), psnr("gather"));
    assert!(drbokeh > gather + 8.0, "drbokeh {drbokeh} dB vs gather {gather} dB");
    assert!(drbokeh > oracle - 2.0 && oracle > 35.0, "drbokeh {drbokeh} dB vs oracle {oracle} dB");
    let sheet = image::open(&sheet).expect("the sheet is a PNG");
    assert!(sheet.width() > 4 * 128 && sheet.height() > 2 * 96, "sheet {}x{}", sheet.width(), sheet.height());
    // Every render as float EXR beside the truth and the input; the drbokeh render read back
    // scores what the table says (the report rounds to 1e-9, the EXR holds the f32 pixels).
    let read = |name: &str| lensblur::stack::read_rgba(&renders.join("small-coc").join(format!("{name}.exr")), None, u64::MAX).unwrap_or_else(|e| panic!("{name}.exr: {e}"));
    let [truth, pinhole, drbokeh_render] = ["truth", "pinhole", "drbokeh"].map(read);
    for name in ["oracle", "gather"] {
        assert_eq!((read(name).width, read(name).height), (pinhole.width, pinhole.height), "{name}.exr size");
    }
    let reread = lensblur::metrics::compare(&drbokeh_render, &truth).expect("same sizes").psnr;
    assert!((reread - drbokeh).abs() < 1e-3, "drbokeh.exr scores {reread} dB, the table {drbokeh} dB");

    // Without Vulkan (the ground truth now comes from the cache): the CPU methods only.
    let (table, warning) = run_ok(&common, &common::NO_VULKAN);
    let cpu: Vec<&str> = lensblur_dev::bench::cpu_methods().iter().map(|m| m.name).collect();
    assert!(warning.contains("no Vulkan device") && warning.contains(&cpu.join(", ")), "{warning}");
    assert!(table.contains("oracle ") && table.contains("gather-cpu ") && !table.contains("drbokeh"), "{table}");
    let mut args = common.to_vec();
    args.extend(["--methods", "drbokeh"]);
    let output = common::lensblur(&args, &common::NO_VULKAN);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && !stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("method 'drbokeh' needs a Vulkan device"), "{stderr}");
}
