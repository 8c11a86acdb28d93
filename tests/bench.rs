//! The benchmark runner on synthetic ground truths whose "defocused" image is the layered
//! oracle itself: proves the registry, the metrics table, the JSON report and the contact
//! sheet work end to end, and that the scoring ranks a perfect method first.
mod common;

use lensblur_dev::bench::{all_methods, contact_sheet, cpu_methods, run, select_methods, write_png, BenchMethod, InputKind};
use lensblur::camera::{Aperture, CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::raytrace::GroundTruth;
use lensblur::render::oracle::render_oracle;
use lensblur::render::{Lens, Method};
use lensblur::stack::{Layer, LayerStack};

const W: usize = 96;
const H: usize = 64;

/// A textured opaque background at `back_z` metres behind a semi-opaque square at 0.4 m.
fn synthetic_truth(name: &str, fstop: f32, back_z: f32) -> GroundTruth {
    let camera = PhysicalCamera { focal_length_mm: 85.0, sensor_width_mm: 36.0, fstop, focus_distance: 2.0 };
    let coc = CocModel::from_physical(&camera, W).expect("valid camera");
    let back = Image::from_fn(W, H, |x, y| {
        let v = if (x / 6 + y / 6) % 2 == 0 { 0.8 } else { 0.1 };
        [v, 0.5 * v, 0.3, 1.0]
    });
    let inside = |x: usize, y: usize| (30..60).contains(&x) && (16..46).contains(&y);
    let front = Image::from_fn(W, H, |x, y| if inside(x, y) { [0.9, 0.9, 0.2, 1.0] } else { [0.0; 4] });
    let layers = vec![
        Layer { name: "front".into(), rgba: front.clone(), disparity: vec![1.0 / 0.4; W * H] },
        Layer { name: "back".into(), rgba: back.clone(), disparity: vec![1.0 / back_z; W * H] },
    ];
    let layers = LayerStack::new(W, H, layers).expect("consistent layers");
    let pinhole = Image::from_fn(W, H, |x, y| if inside(x, y) { front.get(x, y) } else { back.get(x, y) });
    let pinhole_depth = (0..W * H).map(|i| if inside(i % W, i / W) { 0.4 } else { back_z }).collect();
    let defocused = render_oracle(&layers, &Lens { coc, aperture: Aperture::Disk });
    GroundTruth { name: name.into(), camera, coc, pinhole, pinhole_depth, layers, defocused }
}

fn scenes() -> Vec<GroundTruth> {
    // f/4 is the easy scene, f/1.4 blurs 2.9x more and must be every baseline's worst.
    vec![synthetic_truth("mild", 4.0, 5.0), synthetic_truth("strong", 1.4, 5.0)]
}

/// The oracle and the two CPU baselines' references: a fixed set, so the counts below hold when
/// the registry gains a CPU method.
fn three_cpu_methods() -> Vec<BenchMethod> {
    select_methods(cpu_methods(), &["oracle", "gather-cpu", "scatter-cpu"].map(String::from)).expect("registered")
}

#[test]
fn oracle_scores_best_on_its_own_truth() {
    let scenes = scenes();
    let report = run(&scenes, &three_cpu_methods()).expect("benchmark runs");
    let oracle = report.methods.iter().find(|m| m.name == "oracle").expect("oracle registered");
    assert_eq!(oracle.input, InputKind::Layers);
    assert_eq!((oracle.mean.rmse, oracle.mean.psnr), (0.0, f64::INFINITY), "the truth is the oracle itself");
    for other in report.methods.iter().filter(|m| m.name != "oracle") {
        assert_eq!(other.input, InputKind::SingleImage);
        assert!(other.mean.rmse > 1e-3 && other.mean.si_rmse > 0.0, "{}: {:?}", other.name, other.mean);
        assert!(other.mean.psnr < 60.0, "{}", other.name);
        assert!(other.mean.ssim < oracle.mean.ssim && other.mean.zncc < oracle.mean.zncc, "{}", other.name);
        for worst in &other.worst {
            assert_eq!(worst.scene, "strong", "{}: worst {} on {}", other.name, worst.metric, worst.scene);
        }
    }
    assert_eq!(report.cases.len(), 6);
    assert!(report.cases.iter().all(|c| c.seconds >= 0.0 && c.seconds.is_finite()));
}

#[test]
fn report_serialises_to_json_and_prints_one_table() {
    let scenes = scenes();
    let report = run(&scenes, &three_cpu_methods()).expect("benchmark runs");
    let json = serde_json::to_value(&report).expect("serialisable");
    assert_eq!(json["scenes"].as_array().map(Vec::len), Some(2));
    assert_eq!(json["cases"].as_array().map(Vec::len), Some(6));
    assert!(json.get("renders").is_none(), "images stay out of the JSON");
    let oracle = &json["methods"][0];
    assert_eq!(oracle["name"], "oracle");
    assert!(oracle["mean"]["psnr"].is_null(), "infinite PSNR is written as null");
    assert_eq!(oracle["worst"].as_array().map(Vec::len), Some(5));
    let table = report.to_string();
    for needle in ["oracle", "gather", "scatter", "RMSE-s", "PSNR", "SSIM", "ZNCC", "inf", "mild, strong"] {
        assert!(table.contains(needle), "table lacks '{needle}':\n{table}");
    }
    assert_eq!(table.lines().count(), 1 + 3 + 2, "header, one row per method, two legend lines:\n{table}");
}

#[test]
fn contact_sheet_has_a_column_per_method_and_round_trips_as_png() {
    let scenes = scenes();
    let report = run(&scenes, &three_cpu_methods()).expect("benchmark runs");
    let sheet = contact_sheet(&scenes, &report).expect("sheet");
    // Columns: pinhole, truth, 3 methods; each 96 px tile plus 4 px gaps.
    assert_eq!(sheet.width(), 4 + 5 * (96 + 4));
    assert!(sheet.height() > 2 * 2 * 64, "two scenes of two tile rows each");
    let path = std::env::temp_dir().join(format!("lensblur-bench-sheet-{}.png", std::process::id()));
    write_png(&sheet, &path).expect("PNG written");
    let back = image::open(&path).expect("PNG readable").to_rgb8();
    let _ = std::fs::remove_file(&path);
    assert_eq!(back, sheet, "PNG is lossless");
}

#[test]
fn contact_sheet_refuses_renders_of_another_run() {
    let scenes = scenes();
    let report = run(&scenes[..1], &cpu_methods()).expect("benchmark runs");
    assert!(contact_sheet(&scenes, &report).is_err());
}

#[test]
fn methods_are_selected_by_name_and_unknown_names_are_refused() {
    let picked = select_methods(cpu_methods(), &["scatter-cpu".into(), "oracle".into()]).expect("known names");
    let names: Vec<&str> = picked.iter().map(|m| m.name).collect();
    assert_eq!(names, ["oracle", "scatter-cpu"], "registry order is kept");
    let error = select_methods(cpu_methods(), &["nope".into()]).err().expect("unknown name refused");
    assert!(error.to_string().contains("gather"), "the message lists what exists: {error}");
}

#[test]
fn every_renderer_is_registered_with_the_input_it_may_read() {
    let ctx = common::gpu();
    let methods = all_methods(Some(&ctx)).expect("every pipeline builds");
    let listed: Vec<(&str, InputKind)> = methods.iter().map(|m| (m.name, m.input)).collect();
    // Every registry method once, on the input it declares; then the bench-only variants.
    let registry: Vec<(&str, InputKind)> = Method::ALL.iter().map(|m| (m.name(), m.input())).collect();
    let (from_registry, extra): (Vec<_>, Vec<_>) = listed.iter().partition(|m| registry.contains(m));
    assert_eq!(from_registry.len(), registry.len(), "{listed:?}");
    assert!(registry.iter().all(|m| from_registry.contains(&m)), "{listed:?}");
    let single = InputKind::SingleImage;
    let layers = InputKind::Layers;
    let expected = [("drbokeh-auto", single), ("drbokeh-auto-sampled", single), ("drbokeh-deep", layers), ("gather-cpu", single), ("scatter-cpu", single)];
    assert_eq!(extra, expected.iter().collect::<Vec<_>>());
    drop(methods);
    common::finish(ctx);
}

#[test]
fn gpu_baselines_score_as_their_cpu_references() {
    let ctx = common::gpu();
    let names: Vec<String> = ["gather", "scatter", "gather-cpu", "scatter-cpu"].map(String::from).to_vec();
    let methods = select_methods(all_methods(Some(&ctx)).expect("pipelines build"), &names).expect("registered");
    let report = run(&scenes(), &methods).expect("benchmark runs");
    let psnr = |name: &str| report.methods.iter().find(|m| m.name == name).map(|m| m.mean.psnr).expect("ran");
    for base in ["gather", "scatter"] {
        // The renders agree within 1e-5 relative (tests/baselines_gpu.rs): PSNRs within 0.01 dB.
        let (gpu, cpu) = (psnr(base), psnr(&format!("{base}-cpu")));
        assert!((gpu - cpu).abs() < 0.01, "{base}: {gpu} dB on the GPU, {cpu} dB on the CPU");
    }
    drop(methods);
    common::finish(ctx);
}

#[test]
fn a_peer_that_cannot_run_says_why_instead_of_scoring() {
    point_the_peer_nowhere();
    let scenes = scenes();
    match lensblur_dev::bench::run_opendefocus(&scenes) {
        lensblur_dev::bench::PeerRun::Unavailable(reason) => {
            assert!(reason.contains("not built") && reason.contains("/nonexistent/"), "{reason}")
        }
        lensblur_dev::bench::PeerRun::Rendered { .. } => panic!("no peer binary there"),
    }
}

/// Every test of this binary that runs the peer sets the same value (so their order does not
/// matter) and none removes it.
fn point_the_peer_nowhere() {
    std::env::set_var(lensblur_dev::bench::OPENDEFOCUS_ENV, "/nonexistent/lensblur-peer-opendefocus");
}

#[test]
fn single_image_table_has_a_row_per_scene_and_a_peer_column_that_says_why_it_is_empty() {
    point_the_peer_nowhere();
    let scenes = scenes();
    let methods = select_methods(cpu_methods(), &["gather-cpu".into()]).expect("registered");
    let table = lensblur_dev::bench::run_single_image(&scenes, &methods, &indicatif::ProgressBar::hidden(), false).expect("runs");
    assert!(table.peer_missing.as_deref().is_some_and(|r| r.contains("not built")));
    let text = table.to_string();
    for needle in ["opendefocus", "gather-cpu", "mild", "strong", "mean", "worst", "n/a, not built"] {
        assert!(text.contains(needle), "table lacks '{needle}':\n{text}");
    }
    assert_eq!(text.lines().count(), 1 + 2 + 2 + 2, "header, two scenes, mean and worst, two notes:\n{text}");
    assert!(table.psnr("strong", "gather-cpu").is_some_and(|p| p.is_finite()) && table.psnr("strong", "opendefocus").is_none());
}

/// Runs `method` on the three single-image scenes at --quick settings (half resolution, ray
/// traced once into a cache under the target folder) and checks each scene's PSNR floor.
fn assert_single_image_floors(method: &str, floors: [(&str, f64); 3]) {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("single-image-gt");
    let truths = lensblur_dev::bench::scenes::single_image_truths(&[], true, None, Some(&cache)).expect("ray traced");
    let ctx = common::gpu();
    let all = all_methods(Some(&ctx)).expect("pipelines build");
    let methods = select_methods(all, &[method.into()]).expect("registered");
    let report = run(&truths, &methods).expect("benchmark runs");
    let psnr = |scene: &str| report.cases.iter().find(|c| c.scene == scene).map(|c| c.metrics.psnr).expect("ran");
    for (scene, floor) in floors {
        assert!(psnr(scene) >= floor, "{method} on {scene}: {:.2} dB, floor {floor}", psnr(scene));
    }
    drop(methods);
    common::finish(ctx);
}

/// Issue 22: wherever the layered split cannot beat a plain depth-aware gather locally, it must
/// not be worse. Measured as what an oracle gains by taking gather's 16x16 blocks where they are
/// closer to the truth: at --quick 0.09 / 0.28 / 0.00 dB (full size 0.02 / 0.11 / 0.13). A
/// region where the split lost to the gather (a quantised slanted surface, a wrong matte) would
/// show as a block gain of a dB or more; the bound is 0.45 dB on every scene.
#[test]
fn auto_layered_drbokeh_is_nowhere_much_worse_than_the_plain_gather() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("single-image-gt");
    let truths = lensblur_dev::bench::scenes::single_image_truths(&[], true, None, Some(&cache)).expect("ray traced");
    let ctx = common::gpu();
    let all = all_methods(Some(&ctx)).expect("pipelines build");
    let methods = select_methods(all, &["drbokeh-auto".into(), "gather".into()]).expect("registered");
    let report = run(&truths, &methods).expect("benchmark runs");
    let position = |name: &str| report.methods.iter().position(|m| m.name == name).expect("ran");
    let (layered, plain) = (position("drbokeh-auto"), position("gather"));
    for (scene, truth) in truths.iter().enumerate() {
        let renders = &report.renders[scene];
        let gain = lensblur_dev::bench::local_pick_gain(&renders[layered], &renders[plain], &truth.defocused).expect("same size");
        assert!((0.0..=0.45).contains(&gain), "{}: gather's blocks would gain {gain:.2} dB", truth.name);
    }
    drop(methods);
    common::finish(ctx);
}

#[test]
fn auto_layered_drbokeh_keeps_its_psnr_floors_on_the_single_image_scenes() {
    // Measured (lavapipe, `bench single-image --quick`): drbokeh-auto 26.61 / 31.49 / 40.21 dB
    // with issue 46's candidate 13 (hidden regions continue the colour beside them), 26.60 /
    // 31.51 / 40.36 with candidate 12 (the thin-line prior; candidate 11 26.93 / 31.75 / 37.22);
    // 26.24 / 31.73 / 37.25 with issue 46's solved matting; 25.60 / 31.15 / 38.16 with the sampled matting before it
    // (thin-near's blurred wires lost 0.9 dB); before issue 22's light-aware matting,
    // back-colour clamp and light continuation 24.15 / 31.44 / 37.77. Floors: 0.3 dB under the
    // measured values, for another driver's rounding.
    let floors = [("silhouette-hdr", 25.94), ("five-planes", 31.43), ("thin-near", 36.95)];
    assert_single_image_floors("drbokeh-auto", floors);
}

#[test]
fn vdslr_keeps_its_psnr_floors_on_the_single_image_scenes() {
    // Measured (lavapipe; its CPU reference gives the same pixels): vdslr 24.84 / 30.49 /
    // 33.82 dB; before issue 22's mixed edge pixels and 512 lens samples 23.78 / 29.69 / 31.68
    // (hair and the silhouette's outline kept sharp with the HDR light behind them, blurred
    // bars' edges crisp, ghosts of the wires), which fails every floor by 0.5 to 1.8 dB; with
    // them but the mixed pixels' farther trace keeping their own colour (the wires' faint
    // lines) thin-near was 32.44, which fails its floor by 1 dB. Floors: 0.3 dB under the
    // measured values, as above.
    let floors = [("silhouette-hdr", 24.55), ("five-planes", 30.15), ("thin-near", 33.5)];
    assert_single_image_floors("vdslr", floors);
}
