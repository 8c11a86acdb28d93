//! Parameter parsing: aperture specs, depth kinds, method names, and the camera resolution
//! the CLI performs (header attributes -> hints, physical camera -> CoC model). Every input
//! must give a value or an error; accepted values must be usable (finite, non-negative).
#![no_main]
use std::collections::BTreeMap;
use std::str::FromStr;

use libfuzzer_sys::fuzz_target;
use lensblur::camera::{Aperture, CameraHints, CocModel, PhysicalCamera};
use lensblur::render::Method;
use lensblur::stack::DepthKind;

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
});
