//! Deep EXR input (issue 39): deep files of the ray tracer's true layers render as the true
//! layers do; the Weta passes merge without seam or halo; bad deep files are refused before
//! rendering, naming file, part and pixel, with nothing written.
// The command line always reads deep files (it builds the library with its `deep` feature).
mod common;

use std::path::{Path, PathBuf};

use lensblur::camera::{CameraHints, SceneUnit};
use lensblur::image::Image;
use lensblur::input::{load, CameraRequest, InputOptions};
use lensblur::metrics::compare;
use lensblur::raytrace::{builtin_scenes, render_ground_truth, TraceOptions};
use lensblur::render::{InputKind, Method};
use lensblur::stack::deep::{read_deep, write_deep, DeepImage, DeepReadOptions, DeepSample, DeepWriteOptions, PartChoice};

fn data(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("tests/data/openexr-deep").join(name)
}

fn request(focal_length_mm: f32, fstop: f32, focus_distance: f32, sensor_width_mm: f32) -> CameraRequest {
    let physical = CameraHints {
        focal_length_mm: Some(focal_length_mm),
        fstop: Some(fstop),
        focus_distance: Some(focus_distance),
        sensor_width_mm: Some(sensor_width_mm),
    };
    CameraRequest { physical, ..CameraRequest::default() }
}

/// drbokeh from a deep file of every bench scene's true layers is within 0.3 dB (PSNR against
/// the thin-lens truth) of drbokeh from the true layers themselves. The files alternate deep
/// scanline and deep tiled, raw and ZIPS, so both chunk kinds and the decompressor are read.
#[test]
fn deep_files_of_the_true_layers_render_as_the_true_layers() {
    let dir = common::temp_dir("deep_input", "true_layers");
    let ctx = common::gpu();
    let trace = TraceOptions { samples_per_axis: 4, min_rounds: 2, max_rounds: 2, ..TraceOptions::default() };
    let mut report = Vec::new();
    for (i, scene) in builtin_scenes().iter().enumerate() {
        let truth = render_ground_truth(scene, &trace).unwrap();
        let path = dir.join(format!("{}.exr", scene.name));
        let options = DeepWriteOptions { tile: (i % 2 == 1).then_some(32), zip: i % 3 == 0, ..DeepWriteOptions::default() };
        write_deep(&path, &[(None, &DeepImage::from_stack(&truth.layers))], &options).unwrap();
        let camera = &truth.camera;
        let request = request(camera.focal_length_mm, camera.fstop, camera.focus_distance, camera.sensor_width_mm);
        let loaded = load(&path, &InputOptions::default(), &request, &CameraHints::default(), InputKind::Layers).unwrap();
        assert_eq!(loaded.camera.lens.coc, truth.coc, "{}: the same lens", scene.name);
        let method = Method::default();
        let from_deep = method.render(Some(&ctx), &loaded.stack, &loaded.camera.lens).unwrap();
        let from_layers = method.render(Some(&ctx), &truth.layers, &loaded.camera.lens).unwrap();
        let deep_db = compare(&from_deep, &truth.defocused).unwrap().psnr;
        let layers_db = compare(&from_layers, &truth.defocused).unwrap().psnr;
        report.push(format!(
            "{}: deep {deep_db:.2} dB ({} layers), true layers {layers_db:.2} dB ({} layers)",
            scene.name,
            loaded.stack.layers.len(),
            truth.layers.layers.len()
        ));
        assert!(deep_db >= layers_db - 0.3, "{}", report.join("\n"));
    }
    eprintln!("{}", report.join("\n"));
    common::finish(ctx);
}

/// The three Weta passes (cropped), merged: with a lens that blurs nothing the render is
/// the merged deep image flattened (DeepToImage), within 1e-3 anywhere, so the layering cuts
/// no seam; defocused, it has no NaN, alpha stays in [0, 1], and energy is conserved: its
/// total colour and alpha are within 2% of the flattened image's (only light crossing the
/// crop's border differs), so no halo adds or removes light.
#[test]
fn the_weta_passes_merge_without_seam_or_halo() {
    let ctx = common::gpu();
    let options = InputOptions { merge: vec![data("Leaves.exr"), data("Trunks.exr")], ..InputOptions::default() };
    let merged = ["Balls.exr", "Leaves.exr", "Trunks.exr"].map(|f| read_deep(&data(f), &DeepReadOptions::default()).unwrap());
    let flat = lensblur::stack::deep::merge(merged.to_vec(), lensblur::stack::DEFAULT_MAX_PIXELS).unwrap().flatten();
    let sharp = request(50.0, 1.0e4, 140.0, 36.0);
    let loaded = load(&data("Balls.exr"), &options, &sharp, &CameraHints::default(), InputKind::Layers).unwrap();
    let render = Method::default().render(Some(&ctx), &loaded.stack, &loaded.camera.lens).unwrap();
    let worst = common::max_abs_diff(&render, &flat);
    assert!(worst < 1e-3, "in focus, the merge is its flattened image: off by {worst}");

    let defocus = CameraRequest { scene_unit: Some("cm".parse::<SceneUnit>().unwrap()), ..request(100.0, 1.4, 140.0, 36.0) };
    let loaded = load(&data("Balls.exr"), &options, &defocus, &CameraHints::default(), InputKind::Layers).unwrap();
    assert!(loaded.stack.layers.len() >= 3, "balls, crowns and trunks lie at different depths");
    let (lo, hi) = loaded.stack.disparity_range();
    let largest = loaded.camera.lens.coc.max_radius(lo, hi);
    assert!(largest > 5.0, "the nearest crown is blurred ({largest} px)");
    let render = Method::default().render(Some(&ctx), &loaded.stack, &loaded.camera.lens).unwrap();
    assert!(render.pixels.iter().flatten().all(|v| v.is_finite()), "no NaN or Inf");
    assert!(render.pixels.iter().all(|p| p[3] >= -1e-4 && p[3] <= 1.0 + 1e-4), "alpha within [0, 1]");
    let total = |image: &Image, c: usize| image.pixels.iter().map(|p| f64::from(p[c])).sum::<f64>();
    for c in 0..4 {
        let ratio = total(&render, c) / total(&flat, c);
        assert!((ratio - 1.0).abs() < 0.02, "channel {c}: the defocused merge holds {ratio} of the flat image's energy");
    }
    common::finish(ctx);
}

/// A 4x3 deep image: one opaque sample per pixel at depth 2, a second at depth 5 in the
/// first row.
fn small() -> DeepImage {
    let mut pixels = Vec::new();
    for i in 0..12 {
        let mut p = vec![DeepSample { rgba: [0.2, 0.3, 0.4, 1.0], z: 2.0, z_back: 2.0 }];
        if i < 4 {
            p.push(DeepSample { rgba: [0.5, 0.5, 0.5, 1.0], z: 5.0, z_back: 5.5 });
        }
        pixels.push(p);
    }
    let mut offsets = vec![0u64];
    for p in &pixels {
        offsets.push(offsets.last().unwrap() + p.len() as u64);
    }
    DeepImage { width: 4, height: 3, origin: [10, 20], offsets, samples: pixels.concat(), attributes: Default::default() }
}

/// Renders `path` with the CLI; returns its stderr after checking it failed and wrote nothing.
fn refused(dir: &Path, path: &Path, extra: &[&str]) -> String {
    let output = dir.join("out.exr");
    let mut args = vec!["render", path.to_str().unwrap(), "-o", output.to_str().unwrap()];
    args.extend_from_slice(&["--focal-length", "50", "--fstop", "2", "--focus-distance", "2"]);
    args.extend_from_slice(extra);
    let run = common::lensblur(&args, &[]);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(!run.status.success(), "{stderr}");
    assert!(!output.exists(), "nothing is written");
    stderr
}

#[test]
fn bad_deep_files_are_refused_before_rendering_naming_file_part_and_pixel() {
    let dir = common::temp_dir("deep_input", "bad");
    let write = |name: &str, image: &DeepImage, z_back: bool| {
        let path = dir.join(name);
        write_deep(&path, &[(Some("left"), image)], &DeepWriteOptions { z_back, ..DeepWriteOptions::default() }).unwrap();
        path
    };
    // NaN depth at pixel (2, 1) of the 4x3 image at (10, 20): file pixel (12, 21).
    let mut image = small();
    let at = image.offsets[4 + 2] as usize;
    image.samples[at].z = f32::NAN;
    let path = write("nan.exr", &image, false);
    let stderr = refused(&dir, &path, &[]);
    assert!(stderr.contains("nan.exr") && stderr.contains("part 0 'left' pixel (12, 21)") && stderr.contains("Z is NaN"), "{stderr}");

    // ZBack in front of Z.
    let mut image = small();
    image.samples[1].z_back = 4.0;
    let path = write("zback.exr", &image, true);
    let stderr = refused(&dir, &path, &[]);
    assert!(stderr.contains("pixel (10, 20)") && stderr.contains("ZBack 4 is in front of Z 5"), "{stderr}");

    // More samples than the budget: 16 in the file.
    let path = write("budget.exr", &small(), true);
    let stderr = refused(&dir, &path, &["--max-samples", "10"]);
    assert!(stderr.contains("more than 10 deep samples") && stderr.contains("--max-samples"), "{stderr}");
    assert!(lensblur::stack::deep::read_deep(&path, &DeepReadOptions::default()).is_ok(), "the file itself is good");

    // A sample count table inconsistent with the data: the last line (raw, 4 pixels with one
    // float RGBA+Z+ZBack sample each = 24 bytes) claims one sample fewer, then one more.
    let mut bytes = std::fs::read(&path).unwrap();
    let table_end = bytes.len() - 4 * 24;
    let path = dir.join("table.exr");
    for (count, said) in [(3i32, "it counts 3 samples (72 bytes) in the chunk, which holds 96 bytes"), (5, "")] {
        bytes[table_end - 4..table_end].copy_from_slice(&count.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let stderr = refused(&dir, &path, &[]);
        assert!(stderr.contains("table.exr") && stderr.contains("part 0 'left'"), "{stderr}");
        assert!(stderr.contains("pixel (10, 22)") && stderr.contains("sample count table is inconsistent with the data"), "{stderr}");
        assert!(stderr.contains(said), "{stderr}");
    }
    // A count that decreases along the line.
    bytes[table_end - 8..table_end - 4].copy_from_slice(&9i32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let stderr = refused(&dir, &path, &[]);
    assert!(stderr.contains("pixel (10, 22)") && stderr.contains("sample count table is inconsistent"), "{stderr}");
}

/// A stereo file is two parts: the first is read by default, either by name, both with `all`.
#[test]
fn parts_of_a_multi_part_file_are_chosen_by_name_or_merged() {
    let dir = common::temp_dir("deep_input", "parts");
    let path = dir.join("stereo.exr");
    let left = small();
    let mut right = small();
    right.samples.iter_mut().for_each(|s| s.rgba[0] = 0.9);
    write_deep(&path, &[(Some("left"), &left), (Some("right"), &right)], &DeepWriteOptions { half_colour: true, ..Default::default() }).unwrap();
    let read = |part: &str| read_deep(&path, &DeepReadOptions { part: part.parse::<PartChoice>().unwrap(), ..Default::default() });
    let first = read("first").unwrap();
    assert_eq!(first.samples.len(), 16);
    assert_eq!(first.samples[0].rgba[0], half::f16::from_f32(0.2).to_f32());
    assert_eq!(read("right").unwrap().samples[0].rgba[0], half::f16::from_f32(0.9).to_f32());
    assert_eq!(read("1").unwrap().samples[0].rgba[0], half::f16::from_f32(0.9).to_f32());
    assert_eq!(read("all").unwrap().samples.len(), 32);
    let error = read("centre").unwrap_err().to_string();
    assert!(error.contains("no deep part 'centre'") && error.contains("0 'left', 1 'right'"), "{error}");
}

/// `info` reports parts, sample counts and the depth range of a deep file.
#[test]
fn info_describes_deep_files() {
    let run = common::lensblur(&["info", data("Trunks.exr").to_str().unwrap()], &[]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    for needle in ["deep OpenEXR, 1 part(s)", "part 0 'rgba.left': deep scanline, zips", "5400 samples", "depth 209.1971..349.5114"] {
        assert!(stdout.contains(needle), "'{needle}' missing:\n{stdout}");
    }
}

/// The render summary names the scene unit: the flag's, else the header's attribute.
#[test]
fn the_render_summary_names_the_scene_unit_from_the_flag_or_the_header() {
    let dir = common::temp_dir("deep_input", "units");
    let mut image = small();
    image.attributes.insert(lensblur::camera::SCENE_UNIT_ATTRIBUTE.into(), "cm".into());
    let path = dir.join("cm.exr");
    write_deep(&path, &[(None, &image)], &DeepWriteOptions::default()).unwrap();
    let output = dir.join("out.exr");
    let render = |extra: &[&str]| {
        let mut args = vec!["render", path.to_str().unwrap(), "-o", output.to_str().unwrap()];
        args.extend_from_slice(&["--focal-length", "50", "--fstop", "2", "--focus-distance", "300"]);
        args.extend_from_slice(extra);
        let run = common::lensblur(&args, &[]);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        String::from_utf8_lossy(&run.stdout).into_owned()
    };
    let stdout = render(&[]);
    assert!(stdout.contains("scene unit cm (from the header)") && stdout.contains("from 16 deep samples"), "{stdout}");
    let stdout = render(&["--scene-unit", "in"]);
    assert!(stdout.contains("scene unit in") && !stdout.contains("from the header"), "{stdout}");
}
