//! Properties of the Dr.Bokeh CPU reference (src/render/drbokeh). Scenes use K = 10 px per
//! unit disparity and focus at disparity 0.5, so `disparity = 0.5 + s / 10` has signed CoC `s`.
use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::render::disk::{disk_blur_cpu, DiskKernel};
use lensblur::render::drbokeh::{render_cpu, render_cpu_terms, Model, Window};
use lensblur::render::Lens;
use lensblur::stack::{Layer, LayerStack};

const K: f32 = 10.0;
const FOCUS: f32 = 0.5;

/// Disparity whose signed CoC radius is `s` pixels (positive = nearer than focus).
fn disp(s: f32) -> f32 {
    FOCUS + s / K
}

fn lens(aperture: Aperture) -> Lens {
    Lens { coc: CocModel::new(K, FOCUS).unwrap(), aperture }
}

fn layer(w: usize, h: usize, rgba: impl Fn(usize, usize) -> [f32; 4], s: impl Fn(usize, usize) -> f32) -> Layer {
    let rgba = Image::from_fn(w, h, rgba);
    let disparity = (0..w * h).map(|i| disp(s(i % w, i / w))).collect();
    Layer { name: "l".into(), rgba, disparity }
}

fn stack(w: usize, h: usize, layers: Vec<Layer>) -> LayerStack {
    LayerStack::new(w, h, layers).unwrap()
}

/// A deterministic texture with detail at several scales, values in [0.05, 1.05].
fn texture(x: usize, y: usize) -> [f32; 3] {
    let (x, y) = (x as f32, y as f32);
    let a = 0.5 + 0.25 * (0.7 * x).sin() * (0.45 * y).cos() + 0.2 * (0.13 * x + 0.21 * y).sin();
    [a + 0.05, 1.1 - a, 0.55 + 0.4 * (0.31 * x - 0.17 * y).cos()]
}

fn opaque(c: [f32; 3]) -> [f32; 4] {
    [c[0], c[1], c[2], 1.0]
}

fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

#[test]
fn in_focus_pixels_are_unchanged() {
    let (w, h) = (48, 48);
    // In-layer case: in-focus texture left, a bright far (r = 6) texture right, one layer.
    let one = stack(w, h, vec![layer(
        w,
        h,
        |x, y| if x < 24 { opaque(texture(x, y)) } else { opaque(texture(y, x).map(|v| 20.0 * v)) },
        |x, _| if x < 24 { 0.0 } else { -6.0 },
    )]);
    // Inter-layer case: an in-focus square in front of a bright far background.
    let inside = |x: usize, y: usize| (12..36).contains(&x) && (12..36).contains(&y);
    let two = stack(w, h, vec![
        layer(w, h, |x, y| if inside(x, y) { opaque(texture(x, y)) } else { [0.0; 4] }, |_, _| 0.0),
        layer(w, h, |x, y| opaque(texture(y, x).map(|v| 20.0 * v)), |_, _| -6.0),
    ]);
    for (scene, focused) in [(&one, Box::new(|x: usize, _y: usize| x < 24) as Box<dyn Fn(usize, usize) -> bool>), (&two, Box::new(inside))] {
        let out = render_cpu(scene, &lens(Aperture::Disk), Model::DrBokeh).unwrap();
        let mut checked = 0;
        for y in 0..h {
            for x in 0..w {
                if focused(x, y) {
                    let want = scene.layers[0].rgba.get(x, y);
                    let got = out.get(x, y);
                    // Only the pixel itself contributes; f64 maths rounded once to f32.
                    for c in 0..4 {
                        assert!(close(got[c], want[c], 1e-6), "({x},{y}) c{c}: {} vs {}", got[c], want[c]);
                    }
                    checked += 1;
                }
            }
        }
        assert!(checked >= 24 * 24);
    }
}

#[test]
fn constant_colour_stack_stays_constant() {
    let (w, h) = (48, 48);
    let c = [0.3f32, 2.5, 7.0];
    let pm = |a: f32| [c[0] * a, c[1] * a, c[2] * a, a];
    let blob = |x: usize, y: usize| {
        let d = ((x as f32 - 20.0).powi(2) + (y as f32 - 26.0).powi(2)).sqrt();
        (1.0 - (d - 8.0) / 3.0).clamp(0.0, 1.0)
    };
    let scene = stack(w, h, vec![
        layer(w, h, |x, y| pm(blob(x, y)), |x, _| 4.0 + x as f32 / 24.0),
        layer(w, h, |x, y| pm(if (x / 6 + y / 9) % 2 == 0 { 1.0 } else { 0.5 }), |_, y| -1.0 + y as f32 / 16.0),
        layer(w, h, |_, _| pm(1.0), |x, y| -3.0 - (x + y) as f32 / 24.0),
    ]);
    for model in [Model::DrBokeh, Model::Compat] {
        let out = render_cpu(&scene, &lens(Aperture::Disk), model).unwrap();
        for (i, p) in out.pixels.iter().enumerate() {
            // Weights are normalised per layer and sum to one over layers: exact up to rounding.
            for ch in 0..3 {
                assert!(close(p[ch], c[ch], 1e-5), "{model:?} pixel {i} c{ch}: {}", p[ch]);
            }
            assert!(close(p[3], 1.0, 1e-6), "{model:?} pixel {i} alpha {}", p[3]);
        }
    }
}

#[test]
fn opaque_plane_at_constant_coc_equals_disk_blur() {
    let (w, h, r) = (64, 64, 4.3f32);
    let scene = stack(w, h, vec![layer(w, h, |x, y| opaque(texture(x, y)), |_, _| -r)]);
    let out = render_cpu(&scene, &lens(Aperture::Disk), Model::DrBokeh).unwrap();
    let want = disk_blur_cpu(&scene.layers[0].rgba, &DiskKernel::new(r));
    let margin = 6;
    let mut worst = 0.0f32;
    for y in margin..h - margin {
        for x in margin..w - margin {
            for c in 0..4 {
                worst = worst.max((out.get(x, y)[c] - want.get(x, y)[c]).abs());
            }
        }
    }
    // Both are the anti-aliased disk; they differ only in how the 1-px rim is integrated
    // (Hermite ramp vs 8x8 supersampled coverage): ~1% of the rim weight on a unit-range
    // texture, i.e. well under 0.5% of the range.
    assert!(worst < 5e-3, "max |drbokeh - disk_blur| = {worst}");
}

#[test]
fn no_colour_bleeding_from_bright_background_onto_in_focus_edge() {
    let (w, h) = (48, 32);
    let dark = [0.05f32, 0.04, 0.03];
    // Bright HDR background blurred with r = 6, dark subject in focus, edge at x = 24.
    let one = stack(w, h, vec![layer(w, h, |x, _| if x < 24 { opaque(dark) } else { opaque([50.0; 3]) }, |x, _| if x < 24 { 0.0 } else { -6.0 })]);
    let two = stack(w, h, vec![
        layer(w, h, |x, _| if x < 24 { opaque(dark) } else { [0.0; 4] }, |_, _| 0.0),
        layer(w, h, |_, _| opaque([50.0; 3]), |_, _| -6.0),
    ]);
    for scene in [&one, &two] {
        let out = render_cpu(scene, &lens(Aperture::Disk), Model::DrBokeh).unwrap();
        for y in 0..h {
            for x in 0..24 {
                for c in 0..3 {
                    // Not one part in 1e6 of the 1000x brighter background reaches the subject.
                    assert!(close(out.get(x, y)[c], dark[c], 1e-6), "({x},{y}): {:?}", out.get(x, y));
                }
            }
        }
    }
    // A camera with 10x the blur per unit disparity (physical cameras have K in the hundreds):
    // same CoCs, 10x smaller disparity steps. The default model works in CoC pixels and is
    // unchanged; the released occlusion, in raw disparity units, no longer blocks and bleeds.
    let k = 100.0;
    let one_k = stack(w, h, vec![layer(w, h, |x, _| if x < 24 { opaque(dark) } else { opaque([50.0; 3]) }, |x, _| if x < 24 { 0.0 } else { -6.0 })]);
    let rescaled = LayerStack::new(w, h, one_k.layers.into_iter().map(|mut l| {
        l.disparity.iter_mut().for_each(|d| *d = FOCUS + (*d - FOCUS) * K / k);
        l
    }).collect()).unwrap();
    let lens_k = Lens { coc: CocModel::new(k, FOCUS).unwrap(), aperture: Aperture::Disk };
    let ours = render_cpu(&rescaled, &lens_k, Model::DrBokeh).unwrap();
    for x in 0..24 {
        assert!(close(ours.get(x, 16)[0], dark[0], 1e-6), "K=100 ({x}, 16): {:?}", ours.get(x, 16));
    }
    let compat = render_cpu(&rescaled, &lens_k, Model::Compat).unwrap();
    assert!(compat.get(23, 16)[0] > 2.0 * dark[0], "compat edge pixel {:?}", compat.get(23, 16));
}

/// Front-layer fraction along the middle row of a red half plane (x < 48, CoC `r`, near)
/// over an in-focus green background.
fn foreground_profile(model: Model, r: f32) -> Vec<f32> {
    let (w, h) = (96, 32);
    let scene = stack(w, h, vec![
        layer(w, h, |x, _| if x < 48 { [1.0, 0.0, 0.0, 1.0] } else { [0.0; 4] }, |_, _| r),
        layer(w, h, |_, _| [0.0, 1.0, 0.0, 1.0], |_, _| 0.0),
    ]);
    let out = render_cpu(&scene, &lens(Aperture::Disk), model).unwrap();
    (0..w).map(|x| out.get(x, 16)[0]).collect()
}

/// Distance between the last pixel above `1 - eps` and the first below `eps`.
fn fade_extent(profile: &[f32], eps: f32) -> usize {
    let hi = profile.iter().rposition(|&v| v > 1.0 - eps).unwrap();
    let lo = profile.iter().position(|&v| v < eps).unwrap();
    lo - hi
}

#[test]
fn blurred_foreground_fades_across_its_coc() {
    let r = 8.0;
    let p = foreground_profile(Model::DrBokeh, r);
    for x in 1..p.len() {
        assert!(p[x] <= p[x - 1] + 1e-6, "fade is monotonic at {x}: {:?}", &p[40..58]);
    }
    // Fully opaque a CoC inside the edge, fully transparent a CoC outside (+1 px of soft rim).
    assert!(p[48 - 10] > 0.999 && p[48 + 9] < 1e-3, "{:?}", &p[36..60]);
    // Half covered at the edge line (between pixels 47 and 48): symmetric half-disk coverage.
    assert!((p[47] + p[48] - 1.0).abs() < 0.02, "{} {}", p[47], p[48]);
    // 90% -> 10% of a half plane swept by a disk of radius r spans 2 * 0.687 r = 11 px.
    let width = fade_extent(&p, 0.1);
    assert!((10..=13).contains(&width), "drbokeh 10-90% width {width}");
    // The whole fade spans the CoC diameter 2r (+1 px of soft rim on each side).
    let extent = fade_extent(&p, 1e-3);
    assert!((16..=19).contains(&extent), "drbokeh fade extent {extent}");
    // The released box spans about half the CoC diameter, so its fade is about half as long.
    let compat = fade_extent(&foreground_profile(Model::Compat, r), 1e-3);
    assert!((compat as f32) < 0.65 * extent as f32, "compat fade extent {compat} vs {extent}");
}

/// Single opaque black layer at signed CoC `s` with one bright pixel at the centre.
fn point_light(aperture: Aperture, s: f32) -> Image {
    let (w, h) = (48, 48);
    let scene = stack(w, h, vec![layer(w, h, |x, y| if (x, y) == (24, 24) { [100.0, 100.0, 100.0, 1.0] } else { [0.0, 0.0, 0.0, 1.0] }, |_, _| s)]);
    render_cpu(&scene, &lens(aperture), Model::DrBokeh).unwrap()
}

#[test]
fn polygon_aperture_makes_polygonal_bokeh() {
    let hexagon = point_light(Aperture::polygon(6, 0.0, 0.0).unwrap(), -12.0);
    let disk = point_light(Aperture::Disk, -12.0);
    let at = |img: &Image, dx: i64, dy: i64| img.get((24 + dx) as usize, (24 + dy) as usize)[0];
    let plateau = at(&hexagon, 0, 0);
    assert!(plateau > 0.0);
    // Edge direction: the hexagon's flat side is at 12 cos 30 = 10.4 px; (11, 0) has gauge
    // 12.7 >= r + 1/2, exactly outside. The disk still covers it fully.
    assert_eq!(at(&hexagon, 11, 0), 0.0);
    assert!(close(at(&disk, 11, 0), at(&disk, 0, 0), 1e-9));
    // Vertex direction (~30 deg): (9, 5) has gauge 10.4 < r - 1/2, fully inside.
    assert!(close(at(&hexagon, 9, 5), plateau, 1e-9));
    // Rotating the blades by 30 deg swaps the two directions.
    let rotated = point_light(Aperture::polygon(6, 30.0, 0.0).unwrap(), -12.0);
    assert!(close(at(&rotated, 11, 0), plateau, 1e-9));
    // Fully round blades give the disk back.
    let round = point_light(Aperture::polygon(6, 0.0, 1.0).unwrap(), -12.0);
    assert!(round.pixels.iter().zip(&disk.pixels).all(|(a, b)| close(a[0], b[0], 1e-5)));
}

#[test]
fn near_and_far_bokeh_are_mirrored() {
    let triangle = Aperture::polygon(3, 90.0, 0.0).unwrap();
    let near = point_light(triangle.clone(), 9.0);
    let far = point_light(triangle, -9.0);
    let mut asymmetric = false;
    for y in 1..47usize {
        for x in 1..47usize {
            let mirrored = far.get(48 - x, 48 - y)[0];
            assert!(close(near.get(x, y)[0], mirrored, 1e-5), "({x},{y})");
            asymmetric |= (near.get(x, y)[0] - far.get(x, y)[0]).abs() > 1e-3;
        }
    }
    assert!(asymmetric, "a triangle is not point-symmetric, so near and far must differ");
}

#[test]
fn windowed_equals_full_sum() {
    let (w, h) = (64, 48);
    let scene = stack(w, h, vec![
        layer(w, h, |x, y| if (x as i64 - 30).abs() < 9 { opaque(texture(x, y)) } else { [0.0; 4] }, |x, _| 3.0 + x as f32 / 16.0),
        layer(w, h, |x, y| opaque(texture(y, x)), |x, y| if x < 32 { -1.0 + y as f32 / 12.0 } else { -8.0 }),
    ]);
    for (model, aperture) in [(Model::DrBokeh, Aperture::Disk), (Model::DrBokeh, Aperture::polygon(5, 10.0, 0.3).unwrap()), (Model::Compat, Aperture::Disk)] {
        let tiled = render_cpu_terms(&scene, &lens(aperture.clone()), model, Window::Tiled).unwrap();
        let full = render_cpu_terms(&scene, &lens(aperture), model, Window::Full).unwrap();
        let smallest = tiled.layers.iter().flat_map(|l| l.window.iter()).min().copied().unwrap();
        assert!(smallest < 20, "{model:?}: windows must actually be smaller than the image");
        // Skipped sources contribute exact zeros and the rest are summed in the same order.
        for (a, b) in tiled.composite.iter().zip(&full.composite) {
            for c in 0..4 {
                assert!((a[c] - b[c]).abs() <= 1e-12 * b[c].abs().max(1.0), "{model:?}: {a:?} vs {b:?}");
            }
        }
        for (lt, lf) in tiled.layers.iter().zip(&full.layers) {
            assert_eq!(lt.visibility, lf.visibility);
        }
    }
}

#[test]
fn compat_keeps_only_91_percent_of_an_in_focus_pixel() {
    let img = point_light(Aperture::Disk, 0.0);
    let compat = {
        let (w, h) = (48, 48);
        let scene = stack(w, h, vec![layer(w, h, |x, y| if (x, y) == (24, 24) { [100.0, 100.0, 100.0, 1.0] } else { [0.0, 0.0, 0.0, 1.0] }, |_, _| 0.0)]);
        render_cpu(&scene, &lens(Aperture::Disk), Model::Compat).unwrap()
    };
    let kept = compat.get(24, 24)[0] / 100.0;
    // The documented defect: ~91% self weight (softstep(1, 0) against its same-depth halo).
    assert!((0.89..0.93).contains(&kept), "compat keeps {kept}");
    assert!(close(img.get(24, 24)[0], 100.0, 1e-7), "default model keeps all of it");
}
