//! `lensblur render --device`: the CPU path renders what the Vulkan path renders (within the
//! GPU-vs-CPU tolerances of each method), a machine without Vulkan falls back to the CPU with
//! a warning, and a device that cannot be opened is a clear error that writes nothing. Also:
//! every output is byte-identical from run to run, and `lensblur devices` / `--version`.
mod common;
use std::path::{Path, PathBuf};

use lensblur::camera::PhysicalCamera;
use lensblur::image::Image;
use lensblur::render::Method;
use lensblur::stack::{write_stack, Layer, LayerStack, StackWriteOptions};

/// K = 0.025 m * (50/3 * 24 px) = 10 px: visible blur on a 24 px wide frame.
const CAMERA: PhysicalCamera =
    PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 3.0, fstop: 1.0, focus_distance: 4.0 };
const W: usize = 24;
const H: usize = 20;


/// A square subject at 2 m over a checkered wall at 4 m (in focus).
fn write_input(dir: &Path) -> PathBuf {
    write_frame(dir, "shot.exr", W, H)
}

/// [`write_input`]'s scene on a `w` x `h` frame (the subject covers the middle third).
fn write_frame(dir: &Path, name: &str, w: usize, h: usize) -> PathBuf {
    let subject = Image::from_fn(w, h, |x, y| {
        if (w * 7 / 24..w * 2 / 3).contains(&x) && (h / 4..h * 3 / 4).contains(&y) {
            [0.9, 0.2 + 0.02 * (y % 20) as f32, 0.1, 1.0]
        } else {
            [0.0; 4]
        }
    });
    let wall = Image::from_fn(w, h, |x, y| {
        let c = if (x / 3 + y / 3) % 2 == 0 { 0.8 } else { 0.1 };
        [c, c, 1.0 - c, 1.0]
    });
    let layers = vec![
        Layer { name: "subject".into(), rgba: subject, disparity: vec![0.5; w * h] },
        Layer { name: "wall".into(), rgba: wall, disparity: vec![0.25; w * h] },
    ];
    let path = dir.join(name);
    let options = StackWriteOptions { camera: Some(CAMERA), ..StackWriteOptions::default() };
    write_stack(&path, &LayerStack::new(w, h, layers).unwrap(), &options).unwrap();
    path
}

/// Runs `lensblur render INPUT -o OUT EXTRA...`, which must succeed; returns its stderr.
fn run_ok(input: &Path, out: &Path, extra: &[&str], env: &[(&str, &str)]) -> String {
    let mut args = vec!["render", input.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let output = common::lensblur(&args, env);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{args:?} failed: {stderr}");
    stderr
}

fn render(input: &Path, out: &Path, extra: &[&str], env: &[(&str, &str)]) -> (Image, String) {
    let stderr = run_ok(input, out, extra, env);
    (read_rgba(out), stderr)
}

fn read_rgba(path: &Path) -> Image {
    let file = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
    let layer = &file.layer_data[0];
    let channel = |name: &str| -> Vec<f32> {
        let c = layer.channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
        c.sample_data.values_as_f32().collect()
    };
    let (r, g, b, a) = (channel("R"), channel("G"), channel("B"), channel("A"));
    Image { width: W, height: H, pixels: (0..W * H).map(|i| [r[i], g[i], b[i], a[i]]).collect() }
}

/// Largest difference relative to max(1, |cpu|), as tests/drbokeh_gpu.rs measures it.
fn worst_relative(gpu: &Image, cpu: &Image) -> f32 {
    gpu.pixels
        .iter()
        .flatten()
        .zip(cpu.pixels.iter().flatten())
        .map(|(g, c)| (g - c).abs() / c.abs().max(1.0))
        .fold(0.0, f32::max)
}

#[test]
fn cpu_device_matches_the_gpu_within_each_methods_tolerance() {
    let dir = common::temp_dir("cli-device", "match");
    let input = write_input(&dir);
    // drbokeh: f32 GPU against the f64 reference, 5e-5 relative (tests/drbokeh_gpu.rs); vdslr
    // and multiview: the 2e-4 of their own GPU-vs-CPU tests (f32 both sides, long ray marches).
    for (method, tolerance) in [("drbokeh", 5e-5), ("drbokeh-compat", 5e-5), ("vdslr", 2e-4), ("multiview", 2e-4)] {
        let (gpu, _) = render(&input, &dir.join(format!("{method}-gpu.exr")), &["--method", method, "--device", "gpu"], &[]);
        let (cpu, warning) = render(&input, &dir.join(format!("{method}-cpu.exr")), &["--method", method, "--device", "cpu"], &[]);
        assert!(warning.contains("warning") && warning.contains("CPU"), "{method}: no warning: {warning}");
        let worst = worst_relative(&gpu, &cpu);
        assert!(worst < tolerance, "{method}: worst relative difference {worst}");
        let blurred = gpu.pixels.iter().zip(&read_rgba(&input_composite(&dir, &input)).pixels).any(|(a, b)| (a[0] - b[0]).abs() > 0.05);
        assert!(blurred, "{method}: the render changed nothing; the comparison would prove nothing");
    }
}

/// The sharp composite (oracle at K = 0) to check that renders actually blur.
fn input_composite(dir: &Path, input: &Path) -> PathBuf {
    let out = dir.join("sharp.exr");
    if !out.exists() {
        let args = ["--method", "oracle", "--blur", "0", "--focus-disparity", "0"];
        render(input, &out, &args, &[]);
    }
    out
}

#[test]
fn an_unknown_lensblur_device_is_a_clear_error_and_writes_nothing() {
    let dir = common::temp_dir("cli-device", "unknown");
    let input = write_input(&dir);
    let out = dir.join("out.exr");
    let output = common::lensblur(&["render", input.to_str().unwrap(), "-o", out.to_str().unwrap()], &[("LENSBLUR_DEVICE", "nonesuch-gpu")]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && !stderr.contains("panicked"), "{stderr}");
    for needle in ["LENSBLUR_DEVICE=nonesuch-gpu matches no Vulkan device", "lensblur devices", "--device cpu"] {
        assert!(stderr.contains(needle), "'{needle}' missing: {stderr}");
    }
    assert!(!out.exists());
}

#[test]
fn a_device_lost_mid_render_is_an_error_and_leaves_the_old_output_untouched() {
    let dir = common::temp_dir("cli-device", "device-lost");
    let input = write_input(&dir);
    let out = dir.join("out.exr");
    let grads = dir.join("grads.exr");
    // A plain RGBA render serves as the output gradient of `grad`.
    let grad_output = dir.join("g.exr");
    run_ok(&input, &grad_output, &[], &[]);
    std::fs::write(&out, b"previous output").unwrap();
    let before: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    let fault = [("LENSBLUR_TEST_FAULT", "device-lost")];
    let (input, out_s) = (input.to_str().unwrap(), out.to_str().unwrap());
    // `--device gpu`: in auto, a frame this small renders on the CPU without opening a device.
    for args in [
        vec!["render", input, "-o", out_s, "--device", "gpu"],
        vec!["render", input, "-o", out_s, "--method", "gather", "--layers", "*"],
        vec!["grad", input, "--grad-output", grad_output.to_str().unwrap(), "-o", grads.to_str().unwrap()],
    ] {
        let output = common::lensblur(&args, &fault);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success() && !stderr.contains("panicked"), "{args:?}: {stderr}");
        for needle in ["ERROR_DEVICE_LOST", "nothing was written", "--device cpu"] {
            assert!(stderr.contains(needle), "{args:?}: '{needle}' missing: {stderr}");
        }
        assert_eq!(std::fs::read(&out).unwrap(), b"previous output", "{args:?}: the old output is kept");
        let after: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(after, before, "{args:?}: no new or temporary file");
    }
}

#[test]
fn without_vulkan_auto_falls_back_to_the_cpu_and_gpu_refuses() {
    let dir = common::temp_dir("cli-device", "novulkan");
    let input = write_input(&dir);
    // A hexagon: a lens drbokeh's fast CPU path does not render, so auto tries the device.
    let hexagon = ["--aperture", "polygon:6"];
    let (fallback, warning) = render(&input, &dir.join("auto.exr"), &hexagon, &common::NO_VULKAN);
    assert!(warning.contains("no usable Vulkan device") && warning.contains("on the CPU"), "{warning}");
    let (cpu, _) = render(&input, &dir.join("cpu.exr"), &[&hexagon[..], &["--device", "cpu"]].concat(), &[]);
    assert_eq!(fallback.pixels, cpu.pixels, "the fallback is the CPU path");
    let out = dir.join("gpu.exr");
    let output = common::lensblur(&["render", input.to_str().unwrap(), "-o", out.to_str().unwrap(), "--device", "gpu"], &common::NO_VULKAN);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && !stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("opening the Vulkan device") && stderr.contains("--device cpu"), "{stderr}");
    assert!(!out.exists());
}

/// A small one-shot drbokeh frame through a disk renders on the CPU in auto, opening no device:
/// without Vulkan it renders as on a machine with one, without a warning, and with the bytes of
/// `--device cpu`; `--device gpu` still renders it on the device, equal within the GPU's
/// tolerance. A frame above 512x512 pixels, or a lens the fast path does not render, opens the
/// device (the fallback test above).
#[test]
fn a_small_disk_frame_renders_on_the_cpu_without_opening_a_device() {
    let dir = common::temp_dir("cli-device", "small-frame");
    let input = write_input(&dir);
    let report = |stdout: &[u8]| serde_json::from_slice::<serde_json::Value>(stdout).unwrap();
    let auto_out = dir.join("auto.exr");
    let output = common::lensblur(&["render", input.to_str().unwrap(), "-o", auto_out.to_str().unwrap(), "--json"], &common::NO_VULKAN);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success() && !stderr.contains("warning"), "{stderr}");
    assert!(report(&output.stdout)["device"].is_null(), "no device opened");
    let auto = read_rgba(&auto_out);
    let (cpu, _) = render(&input, &dir.join("cpu.exr"), &["--device", "cpu"], &[]);
    assert_eq!(auto.pixels, cpu.pixels, "auto renders the small frame as --device cpu does");
    let gpu_out = dir.join("gpu.exr");
    let output = common::lensblur(&["render", input.to_str().unwrap(), "-o", gpu_out.to_str().unwrap(), "--device", "gpu", "--json"], &[]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(report(&output.stdout)["device"].as_str().is_some_and(|name| !name.is_empty()), "--device gpu opens the device");
    let worst = worst_relative(&read_rgba(&gpu_out), &cpu);
    assert!(worst < 5e-5, "the device and the CPU path agree as in the test above: worst relative difference {worst}");
}

#[test]
fn every_method_renders_bit_identical_files_twice() {
    let dir = common::temp_dir("cli-device", "determinism");
    let input = write_input(&dir);
    for method in Method::ALL.iter().map(|m| m.name()) {
        let outputs: Vec<Vec<u8>> = (0..2)
            .map(|run| {
                let out = dir.join(format!("{method}-{run}.exr"));
                run_ok(&input, &out, &["--method", method], &[]);
                std::fs::read(&out).unwrap()
            })
            .collect();
        assert!(outputs[0] == outputs[1], "{method}: the two runs wrote different bytes");
    }
    let (a, b) = (dir.join("half-0.exr"), dir.join("half-1.exr"));
    for out in [&a, &b] {
        run_ok(&input, out, &["--half", "--output-layer", "Defocus", "--preview", out.with_extension("png").to_str().unwrap()], &[]);
    }
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(), "half output differs between runs");
    assert!(std::fs::read(a.with_extension("png")).unwrap() == std::fs::read(b.with_extension("png")).unwrap());
}

/// Runs `lensblur ARGS` twice (`{run}` in an argument becomes the run's number) and returns
/// the bytes of `output(run)` for both runs.
fn twice(args: &[&str], output: impl Fn(usize) -> PathBuf) -> [Vec<u8>; 2] {
    [0, 1].map(|run| {
        let args: Vec<String> = args.iter().map(|a| a.replace("{run}", &run.to_string())).collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let result = common::lensblur(&args, &[]);
        assert!(result.status.success(), "{args:?} failed: {}", String::from_utf8_lossy(&result.stderr));
        std::fs::read(output(run)).unwrap()
    })
}

#[test]
fn tiled_cpu_and_gradient_outputs_are_bit_identical_twice() {
    let dir = common::temp_dir("cli-device", "determinism-more");
    // 80 x 56 in 16 px tiles: 5 x 4 tiles with halos, so tile order and seams are exercised.
    let (w, h) = (80, 56);
    let frame = write_frame(&dir, "frame.exr", w, h);
    let frame = frame.to_str().unwrap();
    let out = |name: &str| dir.join(name).to_str().unwrap().to_string();
    for method in ["drbokeh", "drbokeh-compat"] {
        let pattern = out(&format!("{method}-tiled-{{run}}.exr"));
        let [a, b] = twice(&["render", frame, "-o", &pattern, "--method", method, "--tile", "16"], |run| {
            dir.join(format!("{method}-tiled-{run}.exr"))
        });
        assert!(a == b, "{method} --tile 16: the two runs wrote different bytes");
    }
    let input = write_input(&dir);
    for method in ["drbokeh", "drbokeh-compat", "multiview", "vdslr"] {
        let pattern = out(&format!("{method}-cpu-{{run}}.exr"));
        let [a, b] = twice(&["render", input.to_str().unwrap(), "-o", &pattern, "--method", method, "--device", "cpu"], |run| {
            dir.join(format!("{method}-cpu-{run}.exr"))
        });
        assert!(a == b, "{method} --device cpu: the two runs wrote different bytes");
    }
    // dL/dB with every sign and several magnitudes, on the tiled frame.
    let g = dir.join("g.exr");
    let gradient = Image::from_fn(w, h, |x, y| [((x * 3 + y) % 7) as f32 / 7.0 - 0.4, 0.3, -0.2 + (y % 3) as f32 * 0.1, 0.0]);
    lensblur::stack::write_image(&g, &gradient, &lensblur::stack::WriteOptions::default()).unwrap();
    let pattern = out("grads-{run}.exr");
    let [a, b] = twice(&["grad", frame, "--grad-output", g.to_str().unwrap(), "-o", &pattern, "--tile", "16"], |run| {
        dir.join(format!("grads-{run}.exr"))
    });
    assert!(a == b, "lensblur grad: the two runs wrote different bytes");
    assert!(a.len() > 1000, "a gradient file of {} bytes holds nothing", a.len());
}

/// `lensblur devices` output: (index, name, marked) per device line.
fn device_lines(env: &[(&str, &str)]) -> (Vec<(usize, String, bool)>, String) {
    let output = common::lensblur(&["devices"], env);
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let devices = stdout
        .lines()
        .filter_map(|line| {
            let (mark, rest) = line.split_at_checked(2)?;
            let (index, name) = rest.split_once(": ")?;
            Some((index.parse().ok()?, name.to_string(), mark == "* "))
        })
        .collect();
    (devices, stdout)
}

#[test]
fn devices_lists_llvmpipe_marks_the_chosen_one_and_follows_lensblur_device() {
    let (devices, listing) = device_lines(&[]);
    let llvmpipe = devices.iter().find(|(_, name, _)| name.contains("llvmpipe")).unwrap_or_else(|| panic!("no llvmpipe: {listing}"));
    assert_eq!(devices.iter().filter(|d| d.2).count(), 1, "exactly one device is marked: {listing}");
    for needle in ["driver:", "workgroup:", "storage buffer range", "push constants", "chosen:"] {
        assert!(listing.contains(needle), "'{needle}' missing: {listing}");
    }
    let index = llvmpipe.0.to_string();
    for wanted in [index.as_str(), "llvmpipe", "LLVMPIPE"] {
        let (devices, listing) = device_lines(&[("LENSBLUR_DEVICE", wanted)]);
        let marked: Vec<_> = devices.iter().filter(|d| d.2).collect();
        assert!(marked.len() == 1 && marked[0].1.contains("llvmpipe"), "LENSBLUR_DEVICE={wanted}: {listing}");
        assert!(listing.contains(&format!("chosen: {index}")), "LENSBLUR_DEVICE={wanted}: {listing}");
    }
    let (devices, listing) = device_lines(&[("LENSBLUR_DEVICE", "nonesuch-gpu")]);
    assert!(devices.iter().all(|d| !d.2) && listing.contains("no device matches LENSBLUR_DEVICE"), "{listing}");
}

#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    use std::process::{Command, Stdio};
    // The reader is gone before lensblur writes: its first line meets a closed pipe.
    let mut child = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["raytrace", "--list"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("lensblur starts");
    drop(child.stdout.take());
    let output = child.wait_with_output().expect("lensblur ends");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!stderr.contains("panicked") && !stderr.contains("Broken pipe"), "{stderr}");
    assert_ne!(output.status.code(), Some(101), "no panic exit: {:?}", output.status);
}
