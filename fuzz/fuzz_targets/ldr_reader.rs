//! Bytes -> PNG/JPEG colour + depth image -> stack input: the LDR reader must answer every
//! pair of files with an input or an error, never a panic, an abort or a huge allocation, and
//! an input it returns must be well formed.
#![no_main]
use lensblur::stack::{read_ldr, DepthKind};
use libfuzzer_sys::fuzz_target;

/// Two scratch files per process (libFuzzer runs inputs one after another in a process).
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm".into() } else { std::env::temp_dir() };
    dir.join(format!("lensblur-fuzz-ldr-{}-{name}", std::process::id()))
}

fuzz_target!(|data: &[u8]| {
    // First byte: where the colour file ends (in 1/256ths of the rest) and the depth kind.
    let Some((&split, rest)) = data.split_first() else { return };
    let at = rest.len() * usize::from(split) / 256;
    let (colour, depth) = rest.split_at(at);
    let (colour_path, depth_path) = (scratch("colour.png"), scratch("depth.png"));
    if std::fs::write(&colour_path, colour).is_err() || std::fs::write(&depth_path, depth).is_err() {
        return;
    }
    let kind = [DepthKind::Disparity, DepthKind::Z, DepthKind::InverseZ][usize::from(split % 3)];
    let max_pixels = 1 << 16;
    if let Ok(input) = read_ldr(&colour_path, &depth_path, kind, max_pixels) {
        let pixels = input.image.width * input.image.height;
        assert!(pixels as u64 <= max_pixels);
        assert_eq!(input.image.pixels.len(), pixels);
        assert_eq!(input.disparity.len(), pixels);
        assert!(input.image.pixels.iter().flatten().all(|v| v.is_finite() && *v >= 0.0), "bad colour accepted");
        assert!(input.disparity.iter().all(|d| d.is_finite() && *d >= 0.0), "bad disparity accepted");
    }
});
