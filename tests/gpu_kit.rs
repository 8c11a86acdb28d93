//! The GPU kit (`gpu-kit/run`) on this machine's Vulkan device (lavapipe in CI) with its small
//! timing cases: the same script, the same self-check and the same report a lent GPU produces,
//! so the kit cannot rot between the sessions that are lent one. The self-check is the one copy
//! of the GPU-against-CPU-reference comparisons (dev/src/selfcheck): every method's forward pass and
//! every backward pass, untiled and tiled, each aperture path and the sequence path.
mod common;

use std::process::Command;

use common::temp_dir;

#[test]
fn the_kit_passes_every_self_check_and_times_every_case_on_this_device() {
    let dir = temp_dir("gpu_kit", "run");
    let out = dir.join("out");
    let run = Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/../gpu-kit/run"))
        .args(["--small", "--repeats", "2", "--bin", env!("CARGO_BIN_EXE_lensblur"), "--out"])
        .arg(&out)
        .env_remove("LENSBLUR_DEVICE")
        .output()
        .unwrap();
    let log = std::fs::read_to_string(out.join("kit.log")).unwrap_or_default();
    let report: serde_json::Value = match std::fs::read_to_string(out.join("report.json")) {
        Ok(text) => serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("report.json is not JSON ({e}):\n{text}\nlog:\n{log}")),
        Err(e) => panic!(
            "no report.json ({e}); the kit printed:\n{}{}",
            String::from_utf8_lossy(&run.stdout),
            String::from_utf8_lossy(&run.stderr)
        ),
    };

    // Every check ran and passed, with validation on and silent.
    let checks =
        report["self_check"]["checks"].as_array().unwrap_or_else(|| panic!("no checks in the report; log:\n{log}"));
    let failed: Vec<String> = checks.iter().filter(|c| c["passed"] != true).map(|c| c.to_string()).collect();
    assert!(failed.is_empty(), "failed self-checks:\n{}\nlog:\n{log}", failed.join("\n"));
    assert!(report["self_check"]["validation_error"].is_null(), "{}", report["self_check"]["validation_error"]);
    let names: Vec<&str> = checks.iter().filter_map(|c| c["name"].as_str()).collect();
    let has = |parts: &[&str]| names.iter().any(|n| parts.iter().all(|p| n.contains(p)));
    for method in lensblur::render::Method::ALL.iter().filter(|m| m.uses_gpu()) {
        let forward = format!("forward {method} ");
        assert!(
            has(&[&forward, "untiled"]) && has(&[&forward, "tiles"]),
            "{method}: forward untiled and tiled checks: {names:?}"
        );
    }
    for (aperture, _) in lensblur_dev::selfcheck::apertures() {
        assert!(has(&["forward drbokeh ", aperture, "tiles"]), "forward {aperture} tiled: {names:?}");
    }
    for aperture in ["disk", "polygon:6", "anamorphic", "ring", "image"] {
        for model in ["DrBokeh", "Compat"] {
            assert!(
                has(&["backward", model, aperture, "untiled"]) && has(&["backward", model, aperture, "tiles"]),
                "backward {model} {aperture}: {names:?}"
            );
        }
    }
    assert!(has(&["sequence"]), "the sequence path: {names:?}");

    // Every timing case has positive wall and device times (lavapipe has timestamp queries).
    let cases = report["timings"]["cases"].as_array().unwrap_or_else(|| panic!("no timings; log:\n{log}"));
    assert_eq!(cases.len(), lensblur_dev::bench::device_timings::timing_cases(true).len());
    for case in cases {
        let positive = |key: &str| case[key].as_f64().is_some_and(|v| v > 0.0 && v.is_finite());
        assert!(positive("wall_ms") && positive("device_ms") && positive("effective_taps_per_second"), "{case}");
        assert_eq!(case["device_ms_runs"].as_array().map(Vec::len), Some(2), "{case}");
    }
    assert!(report["timings"]["backward_over_forward"].as_f64().is_some_and(|r| r > 0.0), "{}", report["timings"]);
    // The whole-process cases: each timed, with its steps and the peak device memory of the
    // render's buffers. Bounds that catch a broken measurement, not issue 44's goal (3x the
    // stack, which the kit reports): at least one layer's input, and no more than the
    // untiled frame's stack, intermediates and output take (5.4x measured at these sizes).
    let processes = report["timings"]["processes"].as_array().unwrap_or_else(|| panic!("no process timings; log:\n{log}"));
    assert_eq!(processes.len(), lensblur_dev::bench::process_timings::process_cases(true).len());
    for process in processes {
        assert!(process["case"]["name"].as_str().is_some_and(|n| n.starts_with("process ")), "{process}");
        assert!(process["wall_ms"].as_f64().is_some_and(|v| v > 0.0), "{process}");
        assert!(process["steps_ms"]["render"].as_f64().is_some_and(|v| v > 0.0), "{process}");
        let over_stack = process["peak_over_stack"].as_f64().unwrap_or_else(|| panic!("no peak device memory: {process}"));
        assert!((0.2..=8.0).contains(&over_stack), "peak device memory {over_stack}x the stack: {process}");
    }
    assert!(report["devices"]["devices"].as_array().is_some_and(|d| !d.is_empty()), "{}", report["devices"]);
    assert_eq!(report["passed"], true, "log:\n{log}");
    assert!(run.status.success(), "the kit exited with {}; log:\n{log}", run.status);
    assert!(log.contains("== lensblur devices") && log.contains("self-check:"), "log:\n{log}");
    // The per-shader device times of one frame's forward and backward: two tables, the
    // backward's passes named in the second.
    let tables: Vec<&str> = log.split("shader (LENSBLUR_PROFILE)").skip(1).collect();
    assert_eq!(tables.len(), 2, "two per-shader tables (forward, grad); log:\n{log}");
    assert!(!tables[0].contains("drbokeh_backward") && tables[0].contains("drbokeh_layer"), "forward table:\n{}", tables[0]);
    assert!(tables[1].contains("drbokeh_backward_source") && tables[1].contains("drbokeh_backward_own"), "grad table:\n{}", tables[1]);
}
