//! On-disk cache of ray-traced ground truths, so repeated benchmark runs skip the tracer.
//! One folder per scene, `<scene>-<key>`, where the key hashes everything the result depends
//! on: the scene's full description (camera, every surface and texture parameter, via its
//! `Debug` form), every sampling option and [`TRACER_VERSION`]. The folder holds `truth.json`
//! (names, camera, sizes) and `truth.bin` (every image as little-endian f32).
use std::path::{Path, PathBuf};

use lensblur::camera::{CocModel, PhysicalCamera};
use lensblur::image::Image;
use lensblur::raytrace::{GroundTruth, Scene, TraceOptions};
use lensblur::stack::{Layer, LayerStack};
use lensblur::{Error, Result};

/// Bump whenever the ray tracer's output changes for the same scene and options.
pub const TRACER_VERSION: u32 = 2;

#[derive(serde::Serialize, serde::Deserialize)]
struct Header {
    name: String,
    camera: PhysicalCamera,
    coc: CocModel,
    width: usize,
    height: usize,
    layers: Vec<String>,
}

/// The folder name of `scene` traced with `options`: `<scene>-<16 hex digits>`.
pub fn cache_key(scene: &Scene, options: &TraceOptions) -> String {
    let o = options;
    let text = format!(
        "v{TRACER_VERSION} {scene:?} n={} scale={} seed={} rounds={}..{} tol={}",
        o.samples_per_axis, o.scale, o.seed, o.min_rounds, o.max_rounds, o.tolerance
    );
    format!("{}-{:016x}", scene.name, fnv1a(text.as_bytes()))
}

/// FNV-1a, 64 bit: stable across Rust versions (std's hasher is not), enough for a cache key.
pub(crate) fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3))
}

/// The cached truth in `dir/key`, or `None` when it is missing or unreadable (re-trace).
pub fn load(dir: &Path, key: &str) -> Option<GroundTruth> {
    let folder = dir.join(key);
    let header: Header = serde_json::from_slice(&std::fs::read(folder.join("truth.json")).ok()?).ok()?;
    let bytes = std::fs::read(folder.join("truth.bin")).ok()?;
    let plane = header.width * header.height;
    let floats: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let mut reader = Floats { data: &floats, at: 0 };
    let (w, h) = (header.width, header.height);
    let pinhole = reader.image(w, h)?;
    let pinhole_depth = reader.take(plane)?.to_vec();
    let defocused = reader.image(w, h)?;
    let mut layers = Vec::new();
    for name in &header.layers {
        let rgba = reader.image(w, h)?;
        layers.push(Layer { name: name.clone(), rgba, disparity: reader.take(plane)?.to_vec() });
    }
    if reader.at != floats.len() {
        return None;
    }
    let layers = LayerStack::new(w, h, layers).ok()?;
    Some(GroundTruth { name: header.name, camera: header.camera, coc: header.coc, pinhole, pinhole_depth, layers, defocused })
}

struct Floats<'a> {
    data: &'a [f32],
    at: usize,
}

impl Floats<'_> {
    fn take(&mut self, n: usize) -> Option<&[f32]> {
        let slice = self.data.get(self.at..self.at + n)?;
        self.at += n;
        Some(slice)
    }

    fn image(&mut self, width: usize, height: usize) -> Option<Image> {
        let pixels = self.take(4 * width * height)?.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
        Some(Image { width, height, pixels })
    }
}


/// Writes `truth` to `dir/key` (through a temporary folder renamed into place, so a crash
/// never leaves a half-written entry that would load).
pub fn store(dir: &Path, key: &str, truth: &GroundTruth) -> Result<PathBuf> {
    let folder = dir.join(key);
    // Unique per writer: tests store the same key from several threads of one process.
    static WRITERS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let writer = WRITERS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let temporary = dir.join(format!(".{key}.{}.{writer}", std::process::id()));
    std::fs::create_dir_all(&temporary).map_err(Error::io(&temporary))?;
    let header = Header {
        name: truth.name.clone(),
        camera: truth.camera,
        coc: truth.coc,
        width: truth.pinhole.width,
        height: truth.pinhole.height,
        layers: truth.layers.layers.iter().map(|l| l.name.clone()).collect(),
    };
    let json = serde_json::to_vec_pretty(&header).map_err(|e| Error::input(&temporary, e.to_string()))?;
    std::fs::write(temporary.join("truth.json"), json).map_err(Error::io(&temporary))?;
    let mut floats: Vec<f32> = Vec::new();
    floats.extend(truth.pinhole.pixels.iter().flatten());
    floats.extend(&truth.pinhole_depth);
    floats.extend(truth.defocused.pixels.iter().flatten());
    for layer in &truth.layers.layers {
        floats.extend(layer.rgba.pixels.iter().flatten());
        floats.extend(&layer.disparity);
    }
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    std::fs::write(temporary.join("truth.bin"), bytes).map_err(Error::io(&temporary))?;
    // A damaged entry (the load that preceded this missed) goes; one that another writer is
    // removing too is gone already.
    match std::fs::remove_dir_all(&folder) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(Error::Io { path: folder, source: e }),
        _ => {}
    }
    if let Err(source) = std::fs::rename(&temporary, &folder) {
        // Another writer stored the same key meanwhile: equal keys are equal truths (the
        // tracer is deterministic), so its entry stands and ours goes.
        let _ = std::fs::remove_dir_all(&temporary);
        if load(dir, key).is_none() {
            return Err(Error::Io { path: folder, source });
        }
    }
    Ok(folder)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lensblur::raytrace::builtin_scene;

    fn tiny_truth() -> GroundTruth {
        let camera = PhysicalCamera { focal_length_mm: 50.0, sensor_width_mm: 36.0, fstop: 2.0, focus_distance: 2.0 };
        let image = |seed: f32| Image::from_fn(5, 3, |x, y| [x as f32 + seed, y as f32, 0.5, 1.0]);
        let layer = |name: &str, seed: f32| Layer { name: name.into(), rgba: image(seed), disparity: vec![seed; 15] };
        GroundTruth {
            name: "tiny".into(),
            camera,
            coc: CocModel::from_physical(&camera, 5).unwrap(),
            pinhole: image(0.25),
            pinhole_depth: (0..15).map(|i| i as f32).collect(),
            layers: LayerStack::new(5, 3, vec![layer("front", 0.5), layer("back", 0.125)]).unwrap(),
            defocused: image(7.0),
        }
    }

    #[test]
    fn stored_truth_loads_back_bit_for_bit_and_damage_means_a_miss() {
        let dir = std::env::temp_dir().join(format!("lensblur-gt-cache-test-{}", std::process::id()));
        let truth = tiny_truth();
        store(&dir, "tiny-0", &truth).unwrap();
        let back = load(&dir, "tiny-0").expect("a stored entry loads");
        assert_eq!((back.name.as_str(), back.camera, back.coc), (truth.name.as_str(), truth.camera, truth.coc));
        assert_eq!((&back.pinhole, &back.pinhole_depth, &back.defocused), (&truth.pinhole, &truth.pinhole_depth, &truth.defocused));
        assert_eq!(back.layers, truth.layers);
        assert!(load(&dir, "tiny-1").is_none(), "another key is a miss");
        let bin = dir.join("tiny-0").join("truth.bin");
        let bytes = std::fs::read(&bin).unwrap();
        std::fs::write(&bin, &bytes[..bytes.len() - 4]).unwrap();
        assert!(load(&dir, "tiny-0").is_none(), "a truncated entry is a miss, not a wrong truth");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn key_changes_with_every_sampling_option_and_the_scene() {
        let scene = builtin_scene("fence").unwrap();
        let base = TraceOptions::default();
        let key = cache_key(&scene, &base);
        assert!(key.starts_with("fence-"), "{key}");
        assert_eq!(key, cache_key(&scene, &TraceOptions { progress: Some(lensblur::raytrace::RowProgress::new(|_, _| {})), ..base.clone() }));
        let variants = [
            TraceOptions { samples_per_axis: 9, ..base.clone() },
            TraceOptions { scale: 0.5, ..base.clone() },
            TraceOptions { seed: 1, ..base.clone() },
            TraceOptions { min_rounds: 5, ..base.clone() },
            TraceOptions { max_rounds: 63, ..base.clone() },
            TraceOptions { tolerance: 0.0021, ..base.clone() },
        ];
        for options in &variants {
            assert_ne!(cache_key(&scene, options), key, "{options:?}");
        }
        let mut moved = scene;
        moved.camera.fstop *= 1.01;
        assert_ne!(cache_key(&moved, &base), key, "a camera change must miss the cache");
    }
}
