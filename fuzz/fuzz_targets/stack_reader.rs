//! Bytes -> layer stack: the reader must answer every input with a stack or an error, never
//! a panic or an abort, and a stack it returns must be well formed.
#![no_main]
use libfuzzer_sys::fuzz_target;
use lensblur::stack::{read_parts, read_stack, DepthKind, ReadOptions};

/// One scratch file per process (libFuzzer runs inputs one after another in a process).
fn scratch() -> std::path::PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm".into() } else { std::env::temp_dir() };
    dir.join(format!("lensblur-fuzz-{}.exr", std::process::id()))
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    if std::fs::write(&path, data).is_err() {
        return;
    }
    // A small budget keeps iterations fast; the budget check itself is under test too.
    let max_pixels = 1 << 16;
    let _ = read_parts(&path, max_pixels);
    for (depth_kind, replace_nonfinite) in [(DepthKind::Z, false), (DepthKind::Disparity, true)] {
        let options = ReadOptions { layers: None, depth_kind, max_pixels, replace_nonfinite };
        if let Ok(file) = read_stack(&path, &options) {
            let stack = &file.stack;
            assert!(stack.width * stack.height <= max_pixels as usize);
            for layer in &stack.layers {
                assert_eq!(layer.rgba.pixels.len(), stack.width * stack.height);
                assert_eq!(layer.disparity.len(), stack.width * stack.height);
                assert!(layer.rgba.pixels.iter().flatten().all(|v| v.is_finite()), "non-finite colour accepted");
                assert!(layer.disparity.iter().all(|d| d.is_finite() && *d >= 0.0), "bad disparity accepted");
            }
        }
    }
});
