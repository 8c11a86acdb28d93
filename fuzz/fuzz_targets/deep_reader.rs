//! Bytes -> deep image -> layer stack: the deep reader (OpenEXR's core library underneath,
//! every count checked on our side) must answer every input with an image or an error, never
//! a panic, an abort or a huge allocation; an image it returns must be well formed, and its
//! layers too. Seeds: files from `lensblur::stack::deep::write_deep` (scanline, tiled, ZIPS,
//! multi-part) and OpenEXR's deep test images.
#![no_main]
use lensblur::camera::CocModel;
use lensblur::stack::deep::{deep_info, deep_to_layers, read_deep, DeepLayerOptions, DeepReadOptions, PartChoice};
use libfuzzer_sys::fuzz_target;

/// One scratch file per process (libFuzzer runs inputs one after another in a process).
fn scratch() -> std::path::PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm".into() } else { std::env::temp_dir() };
    dir.join(format!("lensblur-fuzz-deep-{}.exr", std::process::id()))
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    if std::fs::write(&path, data).is_err() {
        return;
    }
    // Small budgets keep iterations fast; the budget checks themselves are under test too.
    let (max_samples, max_pixels) = (1 << 16, 1 << 16);
    let _ = deep_info(&path, &DeepReadOptions { max_samples, max_pixels, part: PartChoice::First });
    for part in [PartChoice::First, PartChoice::All] {
        let Ok(image) = read_deep(&path, &DeepReadOptions { max_samples, max_pixels, part }) else { continue };
        let n = image.width * image.height;
        assert!(n as u64 <= max_pixels && image.samples.len() as u64 <= max_samples);
        assert_eq!(image.offsets.len(), n + 1);
        assert_eq!(*image.offsets.last().unwrap(), image.samples.len() as u64);
        assert!(image.offsets.windows(2).all(|w| w[0] <= w[1]));
        for s in &image.samples {
            assert!(s.z > 0.0 && s.z_back >= s.z, "bad depth accepted: {s:?}");
            assert!(s.rgba.iter().all(|v| v.is_finite()), "non-finite colour accepted");
        }
        let coc = CocModel::new(8.0, 0.01).unwrap();
        let stack = deep_to_layers(&image, &coc, &DeepLayerOptions::default()).unwrap();
        for layer in &stack.layers {
            assert_eq!(layer.rgba.pixels.len(), n);
            assert!(layer.disparity.iter().all(|d| d.is_finite() && *d >= 0.0), "bad disparity");
        }
    }
});
