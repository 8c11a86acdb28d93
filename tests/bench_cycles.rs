//! Per-scene floors on the Cycles scenes (issue 35): Blender renders the set once (cached in
//! the user cache folder, keyed by the script's text and the settings), drbokeh-auto renders
//! every scene from the pinhole `All` layer + Z, and each scene's PSNR must stay above its
//! floor. Fails, never skips, when Blender is missing: CI installs it.
mod common;

use lensblur_dev::bench::cycles::{cycles_truths, CyclesSettings, CYCLES_SCENES};
use lensblur_dev::bench::{all_methods, run, select_methods};

/// CI's rendering of the set: 128^2 with a 256-sample truth (the benchmark's is 192^2, 512):
/// 3.6 minutes of Blender on 2 shared cores when the cache is cold (measured).
const CI: CyclesSettings = CyclesSettings::with_truth_spp(128, 256);

/// Measured on lavapipe (`lensblur bench single-image --cycles --cycles-size 128
/// --cycles-spp 256`, one run): 26.55 / 30.35 / 27.66 / 23.31 / 17.86 / 19.67 / 24.78 / 35.39 /
/// 37.25 / 31.99 / 36.05 / 34.09 / 26.99 dB in this order; before the thin-structure matting
/// of issue 35 the fences, the grid, the strands and the mast scored 21.55 / 28.70 / 21.51 /
/// 21.09 / 17.94 / 31.17, which fails those floors by 1.3 to 5.9 dB. Floors 0.3 dB below the
/// measured values (the per-scene tolerance), for another driver's rounding.
const DRBOKEH_AUTO_FLOORS: [(&str, f64); 13] = [
    ("fence-near-hdr", 26.25),
    ("fence-far-focus-near", 30.05),
    ("fence-near-135", 27.36),
    ("grid-near", 23.01),
    ("foliage-holes", 17.56),
    ("strands-near", 19.37),
    ("strands-in-focus", 24.48),
    ("mast-sky", 35.09),
    ("specular-near", 36.95),
    ("specular-far", 31.69),
    ("depths-three", 35.75),
    ("edge-crossing", 33.79),
    ("deep-f8", 26.69),
];

#[test]
fn auto_layered_drbokeh_keeps_its_psnr_floor_on_every_cycles_scene() {
    let names: Vec<&str> = DRBOKEH_AUTO_FLOORS.iter().map(|f| f.0).collect();
    assert_eq!(names, CYCLES_SCENES, "a floor per scene, in table order");
    let cache = lensblur::cache_dir::cache_subdir("gt-cache").join("cycles");
    let truths = cycles_truths(&[], &CI, &cache, &|name| eprintln!("Blender rendered {name}")).expect("Blender renders the Cycles scenes");
    let ctx = common::gpu();
    let methods = select_methods(all_methods(Some(&ctx)).expect("pipelines build"), &["drbokeh-auto".into()]).expect("registered");
    let report = run(&truths, &methods).expect("benchmark runs");
    let mut failures = Vec::new();
    for (scene, floor) in DRBOKEH_AUTO_FLOORS {
        let psnr = report.cases.iter().find(|c| c.scene == scene).map(|c| c.metrics.psnr).expect("ran");
        eprintln!("{scene}: {psnr:.2} dB (floor {floor})");
        if psnr < floor {
            failures.push(format!("{scene}: {psnr:.2} dB, floor {floor}"));
        }
    }
    assert!(failures.is_empty(), "drbokeh-auto under its floors: {}", failures.join("; "));
    drop(methods);
    common::finish(ctx);
}
