//! Method settings on `lensblur render` (issue 8): Virtual DSLR's tilt-shift, several focal
//! planes, Eq. 5 highlight weighting, search iterations, and the lens samples of vdslr and
//! multiview, each shown to change the picture the way it should; flags a method does not read
//! are refused. The binary runs with the Vulkan validation layer on.
mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::temp_dir;
use lensblur::image::Image;
use lensblur::render::Method;
use lensblur::stack::{read_rgba, write_stack, Layer, LayerStack, StackWriteOptions};

fn lensblur(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lensblur")).args(args).env("LENSBLUR_VALIDATION", "1").output().unwrap()
}

/// Writes one opaque layer (colour `rgba`, per-pixel disparity; stored as Z = 1/disparity).
fn write_single(dir: &Path, rgba: Image, disparity: Vec<f32>) -> PathBuf {
    let (w, h) = (rgba.width, rgba.height);
    let stack = LayerStack::new(w, h, vec![Layer { name: "image".into(), rgba, disparity }]).unwrap();
    let path = dir.join("shot.exr");
    write_stack(&path, &stack, &StackWriteOptions::default()).unwrap();
    path
}

/// Renders `input` to `name` in its folder with `flags`; returns the image.
fn render(input: &Path, name: &str, flags: &[&str]) -> Image {
    let out = input.with_file_name(name);
    let output = lensblur(&[&["render", input.to_str().unwrap(), "-o", out.to_str().unwrap()], flags].concat());
    assert!(output.status.success(), "lensblur {flags:?} failed: {}", String::from_utf8_lossy(&output.stderr));
    read_rgba(&out, None, 1 << 24).unwrap()
}

/// The error message of a run that must fail (and write nothing).
fn refused(input: &Path, flags: &[&str]) -> String {
    let out = input.with_file_name("refused.exr");
    let output = lensblur(&[&["render", input.to_str().unwrap(), "-o", out.to_str().unwrap()], flags].concat());
    assert!(!output.status.success(), "lensblur {flags:?} should have failed");
    assert!(!out.exists(), "a refused render wrote {}", out.display());
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// A 2-px green/black checker: its contrast survives only where the blur is under ~1 px.
fn checker(w: usize, h: usize) -> Image {
    Image::from_fn(w, h, |x, y| if (x / 2 + y / 2) % 2 == 0 { [0.0, 1.0, 0.0, 1.0] } else { [0.0, 0.0, 0.0, 1.0] })
}

/// Mean absolute difference of the green channel from its row mean, over `rows`.
fn row_contrast(image: &Image, rows: std::ops::Range<usize>) -> f32 {
    let (mut sum, mut n) = (0.0f32, 0usize);
    for y in rows {
        let mean = (0..image.width).map(|x| image.get(x, y)[1]).sum::<f32>() / image.width as f32;
        for x in 0..image.width {
            sum += (image.get(x, y)[1] - mean).abs();
            n += 1;
        }
    }
    sum / n as f32
}

/// Moment radius of channel 0 in a window: a uniform disk of radius R has E[r^2] = R^2 / 2.
fn moment_radius(image: &Image, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
    let taps: Vec<(f64, f64, f64)> = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| (x as f64, y as f64, image.get(x, y)[0] as f64))
        .collect();
    let s: f64 = taps.iter().map(|t| t.2).sum();
    let (cx, cy) = (taps.iter().map(|t| t.0 * t.2).sum::<f64>() / s, taps.iter().map(|t| t.1 * t.2).sum::<f64>() / s);
    let second = taps.iter().map(|&(x, y, v)| v * ((x - cx).powi(2) + (y - cy).powi(2))).sum::<f64>() / s;
    (2.0 * second).sqrt()
}

#[test]
fn tilt_shift_moves_the_band_in_focus_to_the_edge_it_tilts_toward() {
    let dir = temp_dir("cli-methods", "tilt");
    let (w, h) = (40, 40);
    let input = write_single(&dir, checker(w, h), vec![0.5; w * h]);
    // K = 20; the centre focuses 3 CoC px behind the plane (d_f = 0.35), so untilted every
    // row is blurred by 3 px. Tilting by +3 px at the bottom edge brings the bottom rows into
    // focus (d_f there = 0.5) and the top ones to 6 px; -3 does the opposite.
    let camera = ["--method", "vdslr", "--blur", "20", "--focus-disparity", "0.35"];
    let flat = render(&input, "flat.exr", &camera);
    let down = render(&input, "down.exr", &[&camera[..], &["--tilt-shift", "0,3"]].concat());
    let up = render(&input, "up.exr", &[&camera[..], &["--tilt-shift", "0,-3"]].concat());
    let sharp = row_contrast(&checker(w, h), 0..h);
    let (top, bottom) = (0..3, h - 3..h);
    // In focus, every ray hits its own pixel: the checker keeps its contrast (measured: all of
    // it); a CoC of 3 px or more over a 2 px checker leaves under a tenth (measured 4-8%).
    assert!(row_contrast(&down, bottom.clone()) > 0.9 * sharp, "tilt 0,3: bottom rows in focus");
    assert!(row_contrast(&down, top.clone()) < 0.3 * sharp, "tilt 0,3: top rows blurred");
    assert!(row_contrast(&up, top.clone()) > 0.9 * sharp, "tilt 0,-3: top rows in focus");
    assert!(row_contrast(&up, bottom.clone()) < 0.3 * sharp, "tilt 0,-3: bottom rows blurred");
    assert!(row_contrast(&flat, top).max(row_contrast(&flat, bottom)) < 0.3 * sharp, "untilted: no row in focus");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn two_focal_planes_keep_both_distances_sharp_and_blur_between_them() {
    let dir = temp_dir("cli-methods", "planes");
    let (w, h) = (48, 24);
    // Left third at 1 m, middle at 2 m, right third at 4 m (Z stored, physical camera).
    let z = |x: usize| [1.0f32, 2.0, 4.0][x * 3 / w];
    let input = write_single(&dir, checker(w, h), (0..w * h).map(|i| 1.0 / z(i % w)).collect());
    // K = (0.1 / 1) * (100 / 36) * 48 = 13.3 px m: focused at 1 m, 4 m blurs by 10 px; with
    // planes at 1 m and 4 m, the middle (2 m) is 0.25 / m from the nearer plane: 3.3 px.
    let camera = ["--method", "vdslr", "--focal-length", "100", "--fstop", "1", "--sensor-width", "36"];
    let both = render(&input, "both.exr", &[&camera[..], &["--focal-planes", "1,4"]].concat());
    let near = render(&input, "near.exr", &[&camera[..], &["--focus-distance", "1"]].concat());
    let column_change = |image: &Image, x: usize| {
        (0..h).map(|y| (image.get(x, y)[1] - checker(w, h).get(x, y)[1]).abs()).fold(0.0, f32::max)
    };
    // Away from the middle band's 3.3 px reach both outer thirds are exact (rays hit their own
    // pixel); 1e-5 is f32 rounding of the sample average.
    for x in (0..11).chain(w - 11..w) {
        assert!(column_change(&both, x) < 1e-5, "column {x} changed by {}", column_change(&both, x));
    }
    assert!(column_change(&both, w / 2) > 0.2, "the middle band, between the planes, is blurred");
    assert!(column_change(&near, w - 4) > 0.2, "with one plane at 1 m the far third is blurred");
    let message = refused(&input, &[&camera[..], &["--focal-planes", "1,4", "--focus-distance", "2"]].concat());
    assert!(message.contains("--focal-planes replaces --focus-distance"), "{message}");
    let message = refused(&input, &[&camera[..], &["--focal-planes", "1,4", "--near-blur", "2"]].concat());
    assert!(message.contains("cannot be combined with --focal-planes"), "{message}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn highlight_weighting_brightens_the_bokeh_of_highlights_and_leaves_flat_areas_alone() {
    let dir = temp_dir("cli-methods", "highlight");
    let (w, h) = (40, 40);
    // A 3x3 white (clipped, LDR-like) spot on a dim grey plane, blurred to a 6 px CoC.
    let spot = |x: usize, y: usize| (19..22).contains(&x) && (19..22).contains(&y);
    let rgba = Image::from_fn(w, h, |x, y| if spot(x, y) { [1.0; 4] } else { [0.05, 0.05, 0.05, 1.0] });
    let input = write_single(&dir, rgba, vec![0.2; w * h]);
    let camera = ["--method", "vdslr", "--blur", "20", "--focus-disparity", "0.5"];
    let plain = render(&input, "plain.exr", &camera);
    let weighted = render(&input, "weighted.exr", &[&camera[..], &["--highlight-sigma", "0.3"]].concat());
    // Eq. 5 with sigma 0.3: a 0.05 sample weighs exp(-0.95^2 / 0.18) = 0.7% of a white one, so
    // wherever the bokeh disk reaches, the spot's white dominates the average (measured 7.4x
    // brighter on the ring 3-4 px from the spot).
    let ring = |image: &Image| {
        (0..w)
            .flat_map(|x| (0..h).map(move |y| (x, y)))
            .filter(|&(x, y)| {
                let r2 = (x as f32 - 20.0).powi(2) + (y as f32 - 20.0).powi(2);
                (9.0..16.0).contains(&r2)
            })
            .map(|(x, y)| image.get(x, y)[0])
            .sum::<f32>()
    };
    assert!(ring(&weighted) > 2.0 * ring(&plain), "bokeh of the highlight: {} vs {}", ring(&weighted), ring(&plain));
    // Farther than the CoC from the spot every sample has the same colour: the weights cancel.
    for (x, y) in [(3, 3), (36, 5), (5, 35)] {
        assert!((weighted.get(x, y)[0] - 0.05).abs() < 1e-6 && (plain.get(x, y)[0] - 0.05).abs() < 1e-6, "({x}, {y})");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn search_iterations_find_the_background_instead_of_the_nearest_surface() {
    let dir = temp_dir("cli-methods", "iterations");
    let (w, h) = (64, 48);
    // K = 20, focus 0.5: a near square (disparity 1.0, CoC 10 px) sets where every search
    // starts; the background (0.35, CoC 3 px) holds an HDR point light far from the square.
    let near = |x: usize, y: usize| (2..8).contains(&x) && (2..8).contains(&y);
    let rgba = Image::from_fn(w, h, |x, y| {
        if (x, y) == (44, 26) {
            [100.0, 100.0, 100.0, 1.0]
        } else if near(x, y) {
            [0.0, 0.0, 0.5, 1.0]
        } else {
            [0.0, 0.0, 0.0, 1.0]
        }
    });
    let disparity = (0..w * h).map(|i| if near(i % w, i / w) { 1.0 } else { 0.35 }).collect();
    let input = write_single(&dir, rgba, disparity);
    let camera = ["--method", "vdslr", "--blur", "20", "--focus-disparity", "0.5"];
    let none = render(&input, "t0.exr", &[&camera[..], &["--iterations", "0"]].concat());
    let tuned = render(&input, "t10.exr", &[&camera[..], &["--iterations", "10"]].concat());
    let (r0, r10) = (moment_radius(&none, 28, 12, 60, 42), moment_radius(&tuned, 28, 12, 60, 42));
    // With T = 0 a ray only reads where it would meet a surface at the square's disparity and
    // falls back to that pixel: the light spreads over the square's 10 px CoC. One more step
    // reads the background's own disparity and hits: its 3 px CoC (measured moment radii
    // 10.2 and 3.07 px; 0.6 px allows for the pixel-rounded search).
    assert!((r10 - 3.0).abs() < 0.6, "T = 10: light's radius {r10}");
    assert!(r0 > 2.0 * r10, "T = 0: light's radius {r0} vs {r10}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn more_lens_samples_bring_vdslr_and_multiview_closer_to_the_exact_blur() {
    let dir = temp_dir("cli-methods", "samples");
    let (w, h) = (32, 32);
    // One opaque plane blurred by 6 px: the layered oracle's anti-aliased disk blur is the
    // exact answer, so what separates a render from it is the lens-sample estimate (vdslr:
    // noise; multiview: noise, and the wide cones that stand in for missing samples).
    let texture = Image::from_fn(w, h, |x, y| {
        let v = ((x * 7919 + y * 104_729) % 1000) as f32 / 1000.0;
        [v, 1.0 - v, if (x * 13 + y * 7) % 31 == 0 { 8.0 } else { 0.2 }, 1.0]
    });
    let input = write_single(&dir, texture, vec![0.2; w * h]);
    let camera = ["--blur", "20", "--focus-disparity", "0.5"];
    let exact = render(&input, "exact.exr", &[&camera[..], &["--method", "oracle"]].concat());
    // Away from the frame edge, where every method extends the image its own way.
    let error = |image: &Image| {
        let inner = (8..24).flat_map(|y| (8..24).map(move |x| (x, y)));
        let sum: f32 =
            inner.map(|(x, y)| (0..3).map(|c| (image.get(x, y)[c] - exact.get(x, y)[c]).powi(2)).sum::<f32>()).sum();
        (sum / (16.0 * 16.0 * 3.0)).sqrt()
    };
    for method in ["vdslr", "multiview"] {
        let with = |m: &str| {
            render(&input, &format!("{method}-{m}.exr"), &[&camera[..], &["--method", method, "--samples", m]].concat())
        };
        let (few, many) = (error(&with("4")), error(&with("256")));
        // 64 times more samples: measured RMSE 0.41 -> 0.035 (vdslr), 0.040 -> 0.0145
        // (multiview, whose wide cones already smooth the 4-sample render); 2x is the bound.
        assert!(few > 2.0 * many, "{method}: RMSE vs the exact blur {few} with 4 samples, {many} with 256");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn method_flags_are_refused_by_methods_that_do_not_read_them() {
    let dir = temp_dir("cli-methods", "refused");
    let (w, h) = (16, 16);
    let input = write_single(&dir, checker(w, h), vec![0.5; w * h]);
    let camera = ["--blur", "10", "--focus-disparity", "0.5"];
    for (method, flag, value, readers) in [
        ("gather", "--samples", "64", "multiview and vdslr"),
        ("drbokeh", "--samples", "64", "multiview and vdslr"),
        ("multiview", "--iterations", "3", "vdslr"),
        ("oracle", "--highlight-sigma", "0.3", "vdslr"),
        ("scatter", "--tilt-shift", "1,0", "vdslr"),
        ("drbokeh-compat", "--focal-planes", "0.2,0.8", "vdslr"),
    ] {
        let message = refused(&input, &[&camera[..], &["--method", method, flag, value]].concat());
        assert!(message.contains(&format!("{flag} applies to --method {readers}, not {method}")), "{message}");
    }
    let vdslr = [&camera[..], &["--method", "vdslr"]].concat();
    let message = refused(&input, &[&vdslr[..], &["--tilt-shift", "1,0", "--cats-eye", "0.5"]].concat());
    assert!(message.contains("--cats-eye cannot be combined with --tilt-shift"), "{message}");
    let message = refused(&input, &[&vdslr[..], &["--tilt-shift", "1"]].concat());
    assert!(message.contains("expected X,Y"), "{message}");
    let message = refused(&input, &[&vdslr[..], &["--highlight-sigma", "-1"]].concat());
    assert!(message.contains("--highlight-sigma must be a positive number"), "{message}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--tile` and `--max-memory` cut every Vulkan method's frame without changing its output,
/// and are refused, saying why, where the render runs whole on the CPU; a cap below what the
/// frame's input and output take is refused with the numbers.
#[test]
fn tiling_flags_are_honoured_by_every_vulkan_method_and_refused_where_nothing_is_tiled() {
    let dir = temp_dir("cli-methods", "tiling");
    let (w, h) = (40, 28);
    let input = write_single(&dir, checker(w, h), (0..w * h).map(|i| (i % w) as f32 / w as f32).collect());
    let camera = ["--blur", "10", "--focus-disparity", "0.5", "--samples", "16"];
    for method in ["multiview", "vdslr", "gather", "scatter"] {
        let flags: &[&str] = if method == "multiview" || method == "vdslr" { &camera } else { &camera[..4] };
        let whole = render(&input, "whole.exr", &[flags, &["--method", method]].concat());
        let tiled = render(&input, "tiled.exr", &[flags, &["--method", method, "--tile", "7", "--max-memory", "1G"]].concat());
        assert!(whole == tiled, "{method}: --tile 7 changed the output");
    }
    let message = refused(&input, &[&camera[..4], &["--method", "oracle", "--tile", "16"]].concat());
    assert!(message.contains("--tile") && message.contains("oracle runs on the CPU"), "{message}");
    let message = refused(&input, &[&camera[..4], &["--device", "cpu", "--max-memory", "1G"]].concat());
    assert!(message.contains("--max-memory") && message.contains("--device cpu"), "{message}");
    let message = refused(&input, &[&camera[..4], &["--max-memory", "1K"]].concat());
    assert!(message.contains("--max-memory") && message.contains("of 1024 bytes is less than"), "{message}");
    let message = refused(&input, &[&camera[..4], &["--max-memory", "lots"]].concat());
    assert!(message.contains("expected a size such as 512M"), "{message}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The flag check reads the registry: every method accepts exactly the method flags it declares
/// (`lensblur methods --json`), and any other is refused naming the methods that read it.
#[test]
fn every_method_accepts_the_flags_it_declares_and_refuses_the_rest() {
    let dir = temp_dir("cli-methods", "declared");
    let (w, h) = (16, 16);
    let input = write_single(&dir, checker(w, h), vec![0.5; w * h]);
    let camera = ["--blur", "4", "--focus-disparity", "0.5"];
    let listing = lensblur(&["methods", "--json"]);
    assert!(listing.status.success(), "{}", String::from_utf8_lossy(&listing.stderr));
    let listing: serde_json::Value = serde_json::from_slice(&listing.stdout).unwrap();
    let methods = listing["methods"].as_array().unwrap();
    let names: Vec<&str> = methods.iter().map(|m| m["name"].as_str().unwrap()).collect();
    let registry: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
    assert_eq!(names, registry, "the listing is the registry");
    let flags_of = |m: &serde_json::Value| -> Vec<String> {
        m["flags"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string()).collect()
    };
    // A valid value for every method flag (a flag missing here fails the test: add one).
    let value = |flag: &str| match flag {
        "--samples" => "4",
        "--iterations" => "3",
        "--highlight-sigma" => "0.3",
        "--tilt-shift" => "1,0",
        "--focal-planes" => "0.2,0.8",
        other => panic!("no test value for {other}"),
    };
    let all_flags: std::collections::BTreeSet<String> = methods.iter().flat_map(flags_of).collect();
    assert!(all_flags.len() >= 5, "{all_flags:?}");
    for method in methods {
        let name = method["name"].as_str().unwrap();
        let declared = flags_of(method);
        for flag in &all_flags {
            // Focal planes stand for the focus: the camera gives none with them.
            let camera = if flag == "--focal-planes" { &camera[..2] } else { &camera[..] };
            let args = [camera, &["--method", name, flag, value(flag)]].concat();
            if declared.contains(flag) {
                render(&input, &format!("{name}{flag}.exr"), &args);
                continue;
            }
            let readers: Vec<&str> =
                methods.iter().filter(|m| flags_of(m).contains(flag)).map(|m| m["name"].as_str().unwrap()).collect();
            let message = refused(&input, &args);
            let expected = match readers.as_slice() {
                [one] => one.to_string(),
                [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
                [] => unreachable!("{flag} is some method's flag"),
            };
            assert!(message.contains(&format!("{flag} applies to --method {expected}, not {name}")), "{message}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
