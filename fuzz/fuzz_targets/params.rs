//! Parameter parsing: aperture specs, depth kinds, method names, the camera resolution the CLI
//! performs (header attributes -> hints, physical camera -> CoC model), and the lens-character
//! flags (`--bloom T[:GAIN]`, `--focus-at X,Y`, `--chromatic R,G,B`, `--near-blur`/`--far-blur`/
//! `--max-blur`, `--cats-eye`) and `--layers` globs. Every input must give a value or an error;
//! accepted values must be usable (finite, non-negative, inside the image).
#![no_main]
use std::collections::BTreeMap;
use std::str::FromStr;

use libfuzzer_sys::fuzz_target;
use lensblur::camera::{Aperture, CameraHints, CocModel, PhysicalCamera, MAX_COC_RADIUS_PX};
use lensblur::character::{chromatic, focus, Bloom, BlurRemap, CatsEye};
use lensblur::image::Image;
use lensblur::render::{Lens, Method};
use lensblur::stack::naming::glob_match;
use lensblur::stack::{DepthKind, Layer, LayerStack};

fn float(bytes: &[u8], i: usize) -> f32 {
    let mut word = [0u8; 4];
    for (k, w) in word.iter_mut().enumerate() {
        *w = bytes.get(4 * i + k).copied().unwrap_or(0);
    }
    f32::from_le_bytes(word)
}

fuzz_target!(|data: &[u8]| {
    let (numbers, text) = data.split_at(data.len().min(24));
    let text = String::from_utf8_lossy(text);
    // `image:FILE` opens a file: not the parser's business, and the fuzzer must not roam the disk.
    if !text.starts_with("image") {
        if let Ok(aperture) = Aperture::parse(&text) {
            let area = aperture.relative_area();
            assert!(area.is_finite() && area > 0.0, "{text:?}: area {area}");
            let gauge = aperture.gauge(0.6, -0.3);
            assert!(gauge.is_finite() && gauge >= 0.0, "{text:?}: gauge {gauge}");
        }
    }
    let _ = DepthKind::from_str(&text);
    let _ = Method::from_str(&text);
    let mut attributes = BTreeMap::new();
    for line in text.lines() {
        if let Some((key, value)) = line.split_once('=') {
            attributes.insert(key.to_string(), value.to_string());
        }
    }
    let hints = CameraHints::from_attributes(&attributes);
    let width = (float(numbers, 5).to_bits() % 20_000) as usize;
    let camera = PhysicalCamera {
        focal_length_mm: float(numbers, 0),
        sensor_width_mm: hints.sensor_width_mm.unwrap_or(float(numbers, 1)),
        fstop: hints.fstop.unwrap_or(float(numbers, 2)),
        focus_distance: hints.focus_distance.unwrap_or(float(numbers, 3)),
    };
    if let Ok(coc) = CocModel::from_physical(&camera, width) {
        assert!(coc.k_px.is_finite() && coc.k_px >= 0.0, "{camera:?}: K {}", coc.k_px);
        assert!(coc.focus_disparity.is_finite(), "{camera:?}");
    }
    if let Ok(coc) = CocModel::new(float(numbers, 0), float(numbers, 1)) {
        assert!(coc.k_px >= 0.0 && coc.focus_disparity.is_finite());
    }
    character_flags(&text, numbers);
});

/// A 5x4 two-layer stack: a half-covering front layer over an opaque back one.
fn small_stack() -> LayerStack {
    let (w, h) = (5, 4);
    let front = Image::from_fn(w, h, |x, _| if x < 2 { [0.5, 0.2, 0.1, 1.0] } else { [0.0; 4] });
    let back = Image::from_fn(w, h, |_, _| [0.1, 0.4, 0.8, 1.0]);
    let layers = vec![
        Layer { name: "front".into(), rgba: front, disparity: vec![0.8; w * h] },
        Layer { name: "back".into(), rgba: back, disparity: vec![0.2; w * h] },
    ];
    LayerStack::new(w, h, layers).expect("a valid stack")
}

fn character_flags(text: &str, numbers: &[u8]) {
    if let Ok(bloom) = Bloom::parse(text) {
        for v in [0.0, 0.5, 1.0, 20.0] {
            let factor = bloom.factor(v);
            // 1 + (gain - 1) * s with s in [0, 1]; one rounding above the gain at most.
            assert!(factor.is_finite() && factor >= 1.0 && factor <= bloom.gain * (1.0 + 1e-6), "{bloom:?}: factor({v}) = {factor}");
        }
        let boosted = bloom.pixel([0.9, 0.5, 0.2, 1.0]);
        assert!(boosted.iter().all(|c| c.is_finite()), "{bloom:?}: {boosted:?}");
    }
    let stack = small_stack();
    if let Ok([x, y]) = focus::parse_pixel(text) {
        if let Ok(d) = focus::focus_disparity_at(&stack, x, y) {
            assert!(x < stack.width && y < stack.height && d.is_finite(), "{text:?}: ({x}, {y}) -> {d}");
        }
    }
    let Ok(coc) = CocModel::new(float(numbers, 0), float(numbers, 1)) else { return };
    let lens = Lens { coc, aperture: Aperture::default() };
    if let Ok(offsets) = chromatic::parse_offsets(text) {
        assert!(offsets.iter().all(|o| o.is_finite()), "{text:?}: {offsets:?}");
        let render = |stack: &LayerStack, lens: &Lens| {
            assert!(lens.coc.focus_disparity.is_finite(), "{text:?} on {coc:?}: focus {}", lens.coc.focus_disparity);
            Ok(Image::new(stack.width, stack.height))
        };
        let _ = chromatic::render_chromatic(&render, &stack, &lens, offsets);
    }
    let max_px = float(numbers, 4);
    let remap = BlurRemap { near: float(numbers, 2), far: float(numbers, 3), max_px: max_px.is_sign_positive().then_some(max_px) };
    if remap.validate().is_ok() {
        // Absurd multipliers can push a disparity to infinity; every renderer refuses a range
        // whose CoC it cannot draw (check_renderable), and what it accepts must be drawable.
        let mapped = [0.0, 0.25, 0.5, 1.0].map(|d| remap.disparity(d, &coc));
        let lo = mapped.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = mapped.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        if coc.check_renderable(lo, hi).is_ok() {
            let radius = coc.max_radius(lo, hi);
            assert!(radius.is_finite() && radius <= MAX_COC_RADIUS_PX, "{remap:?} on {coc:?}: {mapped:?} -> {radius} px");
        }
    }
    let _ = CatsEye::new(float(numbers, 2));
    // `--layers` globs: a name matches itself and `*` matches every name.
    let (pattern, name) = text.split_once('\n').unwrap_or((text, ""));
    let _ = glob_match(pattern, name);
    assert!(glob_match(pattern, pattern) && glob_match("*", name), "{pattern:?} / {name:?}");
}
