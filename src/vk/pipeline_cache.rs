//! The on-disk pipeline cache: a `VkPipelineCache` loaded from a file named after the device's
//! pipeline-cache UUID when the device opens, and written back when it closes if a pipeline was
//! created meanwhile.
//!
//! Why: drivers compile SPIR-V to machine code at pipeline creation (or, on lavapipe, at first
//! dispatch); keeping that work across processes shortens the short renders a compositing script
//! spawns per frame. A file is only handed to the driver after its header says it was written
//! by the same vendor, device and cache UUID (drivers should reject foreign data themselves, but
//! some crash on it), and it is replaced by rename, so a crash or a concurrent process never
//! leaves a half-written file behind.
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use ash::vk;

use super::error::VkCall;
use crate::atomic_file::write_atomically;
use crate::{Error, Result};

/// `VkPipelineCacheHeaderVersionOne`: header size, version, vendor id, device id, cache UUID.
const HEADER_BYTES: usize = 32;
/// A cache file larger than this is not ours to trust; start empty instead.
const MAX_FILE_BYTES: u64 = 256 << 20;

/// Which driver and device a cache file belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct CacheIdentity {
    pub vendor_id: u32,
    pub device_id: u32,
    pub uuid: [u8; vk::UUID_SIZE],
}

impl CacheIdentity {
    pub(crate) fn of(props: &vk::PhysicalDeviceProperties) -> Self {
        Self { vendor_id: props.vendor_id, device_id: props.device_id, uuid: props.pipeline_cache_uuid }
    }

    /// The cache file for this device inside `dir`; one file per driver build.
    pub(crate) fn file_in(&self, dir: &Path) -> PathBuf {
        let uuid: String = self.uuid.iter().map(|b| format!("{b:02x}")).collect();
        dir.join(format!("pipelines-{:04x}-{:04x}-{uuid}.bin", self.vendor_id, self.device_id))
    }

    /// Whether `data` starts with a version-one header written for this device.
    pub(crate) fn matches(&self, data: &[u8]) -> bool {
        if data.len() < HEADER_BYTES {
            return false;
        }
        let word = |i: usize| u32::from_le_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
        let header_size = word(0) as usize;
        header_size >= HEADER_BYTES
            && header_size <= data.len()
            && word(4) == vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32
            && word(8) == self.vendor_id
            && word(12) == self.device_id
            && data[16..32] == self.uuid
    }
}

/// The default folder: `$XDG_CACHE_HOME/lensblur`, else `$HOME/.cache/lensblur`.
pub(crate) fn default_dir() -> Option<PathBuf> {
    crate::cache_dir::user_cache_dir()
}

pub(crate) struct PipelineCache {
    pub(crate) raw: vk::PipelineCache,
    /// Where to save; `None` keeps the cache in memory only.
    file: Option<PathBuf>,
    /// Bytes of valid data handed to the driver at creation (0: started empty).
    pub(crate) loaded_bytes: usize,
    /// A pipeline was created since loading, so the driver may have more to save.
    dirty: AtomicBool,
}

impl PipelineCache {
    /// Creates the cache, seeded from `file` when it holds data for `identity`.
    pub(crate) fn open(device: &ash::Device, identity: CacheIdentity, file: Option<PathBuf>) -> Result<Self> {
        let initial = file.as_deref().and_then(read_small).filter(|data| identity.matches(data)).unwrap_or_default();
        let info = vk::PipelineCacheCreateInfo::default().initial_data(&initial);
        // SAFETY: `initial` carries a header checked against this device; the driver validates the rest.
        let raw = unsafe { device.create_pipeline_cache(&info, None) }.call("vkCreatePipelineCache")?;
        Ok(Self { raw, file, loaded_bytes: initial.len(), dirty: AtomicBool::new(false) })
    }

    pub(crate) fn file(&self) -> Option<&Path> {
        self.file.as_deref()
    }

    /// Destroys the cache without saving (the device failed to open).
    pub(crate) fn forget(&mut self, device: &ash::Device) {
        self.dirty.store(false, Ordering::Relaxed);
        self.save_and_destroy(device);
    }

    pub(crate) fn mark_dirty(&self) {
        self.dirty.store(true, Ordering::Relaxed);
    }

    /// Writes the driver's data back if anything was added, then destroys the cache. A failure
    /// to save is reported on stderr and otherwise ignored: the cache only saves time.
    pub(crate) fn save_and_destroy(&mut self, device: &ash::Device) {
        if let (Some(file), true) = (&self.file, self.dirty.load(Ordering::Relaxed)) {
            // SAFETY: the cache is live; no pipeline creation can run concurrently (the device is closing).
            match unsafe { device.get_pipeline_cache_data(self.raw) } {
                // Lavapipe (Mesa 22.3) returns the header alone and keeps its own disk cache;
                // the file is still written so drivers that fill it and this code stay one path.
                Ok(data) if data.len() >= HEADER_BYTES => {
                    if let Err(e) = save(file, &data) {
                        eprintln!("lensblur: warning: could not save the pipeline cache {}: {e}", file.display());
                    }
                }
                _ => {}
            }
        }
        // SAFETY: every pipeline created with it has been created; the cache is not used again.
        unsafe { device.destroy_pipeline_cache(self.raw, None) };
        self.raw = vk::PipelineCache::null();
    }
}

/// Replaces `path` by rename (see [`write_atomically`]), creating its folder first.
fn save(path: &Path, data: &[u8]) -> Result<()> {
    let io = Error::io(path);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(io)?;
    }
    write_atomically(path, |w| w.write_all(data).map_err(io))
}

fn read_small(path: &Path) -> Option<Vec<u8>> {
    let size = std::fs::metadata(path).ok()?.len();
    (size <= MAX_FILE_BYTES).then(|| std::fs::read(path).ok()).flatten()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity() -> CacheIdentity {
        CacheIdentity { vendor_id: 0x10005, device_id: 0x0000, uuid: [7; 16] }
    }

    fn header(id: &CacheIdentity) -> Vec<u8> {
        let mut data = Vec::new();
        for word in [32u32, 1, id.vendor_id, id.device_id] {
            data.extend_from_slice(&word.to_le_bytes());
        }
        data.extend_from_slice(&id.uuid);
        data.extend_from_slice(b"payload");
        data
    }

    #[test]
    fn only_a_header_for_the_same_device_is_trusted() {
        let id = identity();
        assert!(id.matches(&header(&id)));
        assert!(!id.matches(&header(&id)[..31]), "truncated header");
        let other_uuid = CacheIdentity { uuid: [8; 16], ..id };
        assert!(!id.matches(&header(&other_uuid)), "another driver build");
        let other_device = CacheIdentity { device_id: 1, ..id };
        assert!(!id.matches(&header(&other_device)), "another device");
        let mut bad_version = header(&id);
        bad_version[4] = 2;
        assert!(!id.matches(&bad_version));
        let mut oversized_header = header(&id);
        oversized_header[0] = 200;
        assert!(!id.matches(&oversized_header), "header size past the data");
    }

    #[test]
    fn the_file_name_says_which_device_and_driver_build() {
        let name = identity().file_in(Path::new("/c")).display().to_string();
        assert_eq!(name, format!("/c/pipelines-10005-0000-{}.bin", "07".repeat(16)));
    }
}
