//! Physical-device choice and the logical device: the [`Context`] every GPU path runs on.
//!
//! Choice: discrete > integrated > virtual > CPU, overridable with `LENSBLUR_DEVICE=<index|name
//! substring>`. One compute queue. The allocator lives inside the device and is dropped before
//! `vkDestroyDevice`; the device waits idle first, so nothing dies under a running submission.
use std::any::Any;
use std::mem::ManuallyDrop;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::error::VkCall;
use super::instance::Instance;
use super::pipeline_cache::{self, CacheIdentity, PipelineCache};
use super::pool::{BufferPool, PoolCounts};
use crate::{Error, Result};

/// How to open the GPU: validation on/off, which device, where compiled pipelines are kept.
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    pub validation: bool,
    /// A device index (as `lensblur devices` lists them) or a case-insensitive name substring.
    pub device: Option<String>,
    /// Folder of the on-disk pipeline cache; `None` keeps compiled pipelines in memory only.
    pub pipeline_cache: Option<PathBuf>,
    /// Testing aid, not a user setting: move every upload and read-back through host-visible
    /// staging memory and a copy, as on discrete GPUs whose device-local memory the host cannot
    /// map, also on a device whose memory it can (lavapipe, integrated GPUs).
    #[doc(hidden)]
    pub staged_transfers: bool,
}

impl ContextOptions {
    /// `LENSBLUR_VALIDATION=1`, `LENSBLUR_DEVICE=<index|name>` and
    /// `LENSBLUR_PIPELINE_CACHE=<folder|off>` (default `$XDG_CACHE_HOME/lensblur`, else
    /// `~/.cache/lensblur`).
    pub fn from_env() -> Self {
        let validation = std::env::var("LENSBLUR_VALIDATION").is_ok_and(|v| !v.is_empty() && v != "0");
        let device = std::env::var("LENSBLUR_DEVICE").ok().filter(|v| !v.is_empty());
        let pipeline_cache = match std::env::var_os("LENSBLUR_PIPELINE_CACHE") {
            Some(v) if v == "off" || v == "0" => None,
            Some(v) if !v.is_empty() => Some(PathBuf::from(v)),
            _ => pipeline_cache::default_dir(),
        };
        Self { validation, device, pipeline_cache, staged_transfers: false }
    }
}

/// What `lensblur devices` shows, and what the tiler and benchmarks need to know.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceInfo {
    pub index: usize,
    pub name: String,
    pub kind: String,
    pub driver: String,
    pub api_version: String,
    pub device_local_bytes: u64,
    pub max_allocation_bytes: u64,
    /// VK_EXT_memory_budget is supported: [`Context::memory_budget`] reads the driver's budget.
    pub memory_budget_extension: bool,
    pub max_workgroup_invocations: u32,
    pub max_workgroup_size: [u32; 3],
    pub max_workgroup_count: [u32; 3],
    pub max_storage_buffer_range: u32,
    /// Texels a uniform texel buffer binding may hold, and the alignment of its offset.
    pub max_texel_buffer_elements: u32,
    pub min_texel_buffer_offset_alignment: u64,
    pub max_push_constants_size: u32,
    pub max_shared_memory_bytes: u32,
    /// Invocations per subgroup (8 on lavapipe's 256-bit build, 32 on NVIDIA): no shader relies
    /// on it, the GPU kit reports it beside the timings.
    pub subgroup_size: u32,
    pub has_compute_queue: bool,
    /// Nanoseconds per timestamp tick, if the compute queue supports timestamps.
    pub timestamp_period_ns: Option<f32>,
}

impl DeviceInfo {
    /// A CPU device (a software rasterizer such as lavapipe): its shaders run on the host's cores.
    pub fn is_cpu(&self) -> bool {
        self.kind == kind_name(vk::PhysicalDeviceType::CPU)
    }
}

/// Device memory available to this process, as [`Context::memory_budget`] measures it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct MemoryBudget {
    /// Bytes of the largest device-local heap this process may still allocate.
    pub available_bytes: u64,
    /// Measured: VK_EXT_memory_budget's budget minus usage, or for a CPU device (whose heap is
    /// system memory) the smaller of the heap and the system's available memory. False: the
    /// heap's whole size, with nothing known of what others hold.
    pub measured: bool,
}

/// `MemAvailable` of /proc/meminfo in bytes (Linux), if readable.
fn system_available_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = meminfo.lines().find(|line| line.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

fn kind_rank(kind: vk::PhysicalDeviceType) -> u32 {
    match kind {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    }
}

fn kind_name(kind: vk::PhysicalDeviceType) -> &'static str {
    match kind {
        vk::PhysicalDeviceType::DISCRETE_GPU => "discrete GPU",
        vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated GPU",
        vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual GPU",
        vk::PhysicalDeviceType::CPU => "CPU",
        _ => "other",
    }
}

fn compute_queue_family(instance: &Instance, device: vk::PhysicalDevice) -> Option<(u32, u32)> {
    // SAFETY: `device` was enumerated from this live instance.
    let families = unsafe { instance.raw.get_physical_device_queue_family_properties(device) };
    families
        .iter()
        .enumerate()
        .find(|(_, f)| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
        .map(|(i, f)| (i as u32, f.timestamp_valid_bits))
}

/// The index of the largest device-local heap (where device buffers live).
fn device_local_heap(memory: &vk::PhysicalDeviceMemoryProperties) -> Option<usize> {
    let heaps = &memory.memory_heaps[..memory.memory_heap_count as usize];
    (0..heaps.len())
        .filter(|&i| heaps[i].flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
        .max_by_key(|&i| heaps[i].size)
}

fn supports_memory_budget(instance: &Instance, device: vk::PhysicalDevice) -> bool {
    // SAFETY: `device` was enumerated from this live instance.
    let extensions = unsafe { instance.raw.enumerate_device_extension_properties(device) }.unwrap_or_default();
    extensions.iter().any(|e| e.extension_name_as_c_str() == Ok(ash::ext::memory_budget::NAME))
}

fn describe(instance: &Instance, index: usize, device: vk::PhysicalDevice) -> DeviceInfo {
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
    // SAFETY: `device` belongs to this live instance; the chained struct outlives the call.
    let (memory, props) = unsafe {
        instance.raw.get_physical_device_properties2(device, &mut props2);
        (instance.raw.get_physical_device_memory_properties(device), props2.properties)
    };
    let mut maintenance3 = vk::PhysicalDeviceMaintenance3Properties::default();
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut props2b = vk::PhysicalDeviceProperties2::default().push_next(&mut maintenance3).push_next(&mut subgroup);
    // SAFETY: as above.
    unsafe { instance.raw.get_physical_device_properties2(device, &mut props2b) };
    let limits = props.limits;
    let device_local_bytes = device_local_heap(&memory).map_or(0, |i| memory.memory_heaps[i].size);
    let queue = compute_queue_family(instance, device);
    let text = |s: Result<&std::ffi::CStr, std::ffi::FromBytesUntilNulError>| {
        s.map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
    };
    let v = props.api_version;
    DeviceInfo {
        index,
        name: text(props.device_name_as_c_str()),
        kind: kind_name(props.device_type).to_string(),
        driver: format!("{} {}", text(driver.driver_name_as_c_str()), text(driver.driver_info_as_c_str()))
            .trim()
            .to_string(),
        api_version: format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v)),
        device_local_bytes,
        max_allocation_bytes: maintenance3.max_memory_allocation_size,
        memory_budget_extension: supports_memory_budget(instance, device),
        max_workgroup_invocations: limits.max_compute_work_group_invocations,
        max_workgroup_size: limits.max_compute_work_group_size,
        max_workgroup_count: limits.max_compute_work_group_count,
        max_storage_buffer_range: limits.max_storage_buffer_range,
        max_texel_buffer_elements: limits.max_texel_buffer_elements,
        min_texel_buffer_offset_alignment: limits.min_texel_buffer_offset_alignment,
        max_push_constants_size: limits.max_push_constants_size,
        max_shared_memory_bytes: limits.max_compute_shared_memory_size,
        subgroup_size: subgroup.subgroup_size,
        has_compute_queue: queue.is_some(),
        timestamp_period_ns: queue
            .filter(|&(_, bits)| bits > 0 && limits.timestamp_period > 0.0)
            .map(|_| limits.timestamp_period),
    }
}

/// Picks the device index to use: the override if given, else the best-ranked with compute.
fn choose(
    instance: &Instance,
    devices: &[vk::PhysicalDevice],
    infos: &[DeviceInfo],
    wanted: Option<&str>,
) -> Result<usize> {
    let usable: Vec<usize> = (0..infos.len()).filter(|&i| infos[i].has_compute_queue).collect();
    if let Some(wanted) = wanted {
        let found = match wanted.trim().parse::<usize>() {
            Ok(index) => usable.iter().copied().find(|&i| i == index),
            Err(_) => {
                let needle = wanted.to_lowercase();
                usable.iter().copied().find(|&i| infos[i].name.to_lowercase().contains(&needle))
            }
        };
        let list: Vec<String> = infos.iter().map(|d| format!("{}: {}", d.index, d.name)).collect();
        return found.ok_or_else(|| {
            Error::NoVulkan(format!(
                "LENSBLUR_DEVICE={wanted} matches no Vulkan device with compute; devices: [{}]",
                list.join(", ")
            ))
        });
    }
    usable
        .into_iter()
        .min_by_key(|&i| {
            // SAFETY: enumerated from this live instance.
            let props = unsafe { instance.raw.get_physical_device_properties(devices[i]) };
            (kind_rank(props.device_type), i)
        })
        .ok_or_else(|| {
            Error::NoVulkan(
                "no Vulkan device with a compute queue was found (install mesa-vulkan-drivers for lavapipe)".into(),
            )
        })
}

/// Lists every Vulkan device, and the index the options would choose (if any).
pub fn list_devices(options: &ContextOptions) -> Result<(Vec<DeviceInfo>, Option<usize>)> {
    let instance = Instance::new(options.validation)?;
    let devices = instance.physical_devices()?;
    let infos: Vec<DeviceInfo> = devices.iter().enumerate().map(|(i, &d)| describe(&instance, i, d)).collect();
    let chosen = choose(&instance, &devices, &infos, options.device.as_deref()).ok();
    instance.log.check()?;
    Ok((infos, chosen))
}

pub(crate) struct Device {
    allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) raw: ash::Device,
    debug_utils: Option<ash::ext::debug_utils::Device>,
    queue: Mutex<vk::Queue>,
    physical: vk::PhysicalDevice,
    pub(crate) pipeline_cache: PipelineCache,
    pub(crate) queue_family: u32,
    pub(crate) info: DeviceInfo,
    pub(crate) instance: Arc<Instance>,
    /// [`ContextOptions::staged_transfers`].
    pub(crate) staged_transfers: bool,
    /// The largest work per tile a render on this device has measured it can take in time
    /// (the tiler's, `crate::render::tiler`); 0 until one has.
    learned_tile_work: std::sync::atomic::AtomicU64,
    /// Every buffer's memory, kept for reuse between its buffers ([`super::pool`]).
    pub(crate) buffer_pool: BufferPool,
}

impl Device {
    pub(crate) fn allocator(&self) -> MutexGuard<'_, Allocator> {
        self.allocator.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(crate) fn queue(&self) -> MutexGuard<'_, vk::Queue> {
        self.queue.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Errors out if the validation layer said anything since the last check.
    pub(crate) fn check_validation(&self) -> Result<()> {
        self.instance.log.check()
    }

    /// Names a Vulkan object so validation messages say which buffer or pipeline they mean.
    pub(crate) fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        let Some(debug_utils) = &self.debug_utils else { return };
        let Ok(name) = std::ffi::CString::new(name) else { return };
        let info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(handle).object_name(&name);
        // SAFETY: `handle` is a live object of this device; naming is advisory, errors ignored.
        let _ = unsafe { debug_utils.set_debug_utils_object_name(&info) };
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: every object of this device holds an Arc to it, so they are all gone; waiting
        // idle covers submissions whose fence nobody waited for. The pool's idle buffers, then
        // the allocator's memory blocks, are freed before the device is destroyed.
        unsafe {
            let _ = self.raw.device_wait_idle();
            self.destroy_buffer_memory(self.buffer_pool.drain_idle());
            self.pipeline_cache.save_and_destroy(&self.raw);
            ManuallyDrop::drop(&mut self.allocator);
            self.raw.destroy_device(None);
        }
    }
}

/// An open GPU: cheap to clone, every Vulkan object made from it keeps it alive.
#[derive(Clone)]
pub struct Context {
    pub(crate) device: Arc<Device>,
    /// What the modules built on the device made and keep for reuse while the context lives,
    /// shared by all clones (today: every compute pipeline, so a renderer made again, as each
    /// frame of a shot makes its own, gets them without creating them anew). Held without
    /// their types so this module needs none of the modules that build on it.
    pub(crate) kept: Arc<Mutex<Vec<Arc<dyn Any + Send + Sync>>>>,
}

impl Context {
    pub fn new(options: &ContextOptions) -> Result<Self> {
        let instance = Arc::new(Instance::new(options.validation)?);
        let devices = instance.physical_devices()?;
        let infos: Vec<DeviceInfo> = devices.iter().enumerate().map(|(i, &d)| describe(&instance, i, d)).collect();
        let index = choose(&instance, &devices, &infos, options.device.as_deref())?;
        let physical = devices[index];
        let (queue_family, _) = compute_queue_family(&instance, physical).expect("chosen devices have a compute queue");
        let priorities = [1.0f32];
        let queues =
            [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
        let extensions = [ash::ext::memory_budget::NAME.as_ptr()];
        let enabled = if infos[index].memory_budget_extension { &extensions[..] } else { &[] };
        let info = vk::DeviceCreateInfo::default().queue_create_infos(&queues).enabled_extension_names(enabled);
        // SAFETY: `physical` belongs to `instance`; `info` points to locals that outlive the call.
        let raw = unsafe { instance.raw.create_device(physical, &info, None) }.call("vkCreateDevice")?;
        // SAFETY: the family was requested with one queue above.
        let queue = unsafe { raw.get_device_queue(queue_family, 0) };
        // SAFETY: `physical` belongs to this live instance.
        let identity = CacheIdentity::of(&unsafe { instance.raw.get_physical_device_properties(physical) });
        let cache_file = options.pipeline_cache.as_deref().map(|dir| identity.file_in(dir));
        let mut pipeline_cache = match PipelineCache::open(&raw, identity, cache_file) {
            Ok(c) => c,
            Err(e) => {
                // SAFETY: nothing was created on the device yet.
                unsafe { raw.destroy_device(None) };
                return Err(e);
            }
        };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.raw.clone(),
            device: raw.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                pipeline_cache.forget(&raw);
                // SAFETY: only the (now destroyed) cache was created on the device.
                unsafe { raw.destroy_device(None) };
                return Err(e.into());
            }
        };
        let debug_utils =
            instance.validation_enabled().then(|| ash::ext::debug_utils::Device::new(&instance.raw, &raw));
        let device = Device {
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            raw,
            debug_utils,
            queue: Mutex::new(queue),
            physical,
            pipeline_cache,
            queue_family,
            info: infos[index].clone(),
            instance,
            staged_transfers: options.staged_transfers,
            learned_tile_work: Default::default(),
            buffer_pool: BufferPool::default(),
        };
        device.check_validation()?;
        log::info!("Vulkan device: {} ({})", device.info.name, device.info.driver);
        Ok(Self { device: Arc::new(device), kept: Arc::default() })
    }

    /// Opens the device chosen by `LENSBLUR_DEVICE` / `LENSBLUR_VALIDATION`.
    pub fn from_env() -> Result<Self> {
        Self::new(&ContextOptions::from_env())
    }

    pub fn info(&self) -> &DeviceInfo {
        &self.device.info
    }

    /// The work per tile that renders on this context measured the device can take (0: none
    /// has): later renders start their tiles there.
    pub(crate) fn learned_tile_work(&self) -> u64 {
        self.device.learned_tile_work.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Remembers a measured work bound (the largest yet is kept).
    pub(crate) fn learn_tile_work(&self, work: u64) {
        self.device.learned_tile_work.fetch_max(work, std::sync::atomic::Ordering::Relaxed);
    }

    pub fn validation_enabled(&self) -> bool {
        self.device.instance.validation_enabled()
    }

    /// Errors out if the validation layer reported anything since the last check.
    pub fn check_validation(&self) -> Result<()> {
        self.device.check_validation()
    }

    /// Drops this handle and reports validation messages raised while tearing the device down
    /// (object leaks, destruction order). Call it last in a command or a test.
    pub fn finish(self) -> Result<()> {
        self.check_validation()?;
        drop(self);
        super::validation::check_unreported()
    }

    /// Device memory this process may still allocate on the largest device-local heap: the
    /// driver's budget minus the heap's current usage where VK_EXT_memory_budget is supported
    /// (both change as this and other processes allocate, so this asks now), else the heap's
    /// size, which other processes may already be using.
    pub fn memory_budget(&self) -> MemoryBudget {
        let device = &self.device;
        let mut budget = vk::PhysicalDeviceMemoryBudgetPropertiesEXT::default();
        let mut properties = vk::PhysicalDeviceMemoryProperties2::default();
        if device.info.memory_budget_extension {
            properties = properties.push_next(&mut budget);
        }
        // SAFETY: the physical device belongs to this live instance; the chained struct (only
        // when the extension is supported and enabled) outlives the call.
        unsafe { device.instance.raw.get_physical_device_memory_properties2(device.physical, &mut properties) };
        let memory = properties.memory_properties;
        let Some(heap) = device_local_heap(&memory) else {
            return MemoryBudget { available_bytes: 0, measured: false };
        };
        // The pool's idle buffers count as available: it drops them when memory is short.
        let idle = device.buffer_pool.counts().idle_bytes;
        if device.info.memory_budget_extension && budget.heap_budget[heap] > 0 {
            let available_bytes = budget.heap_budget[heap].saturating_sub(budget.heap_usage[heap]) + idle;
            return MemoryBudget { available_bytes: available_bytes.min(budget.heap_budget[heap]), measured: true };
        }
        let heap_bytes = memory.memory_heaps[heap].size;
        // A CPU device (lavapipe, CI's device) allocates from system memory, which the kernel
        // accounts for: the heap less what this context holds, and at most what is available.
        if device.info.is_cpu() {
            if let Some(system) = system_available_bytes() {
                let held = self.allocated_bytes().saturating_sub(idle);
                let available_bytes = heap_bytes.saturating_sub(held).min(system + idle);
                return MemoryBudget { available_bytes, measured: true };
            }
        }
        MemoryBudget { available_bytes: heap_bytes, measured: false }
    }

    /// The file compiled pipelines are loaded from and saved to, if any.
    pub fn pipeline_cache_file(&self) -> Option<&Path> {
        self.device.pipeline_cache.file()
    }

    /// Bytes of pipeline-cache data read from disk and accepted when the device opened (0 when
    /// there was no file, or it belonged to another device or driver build).
    pub fn pipeline_cache_loaded_bytes(&self) -> usize {
        self.device.pipeline_cache.loaded_bytes
    }

    /// Bytes currently allocated on the device by this context (idle pooled buffers included).
    pub fn allocated_bytes(&self) -> u64 {
        self.device.allocator().generate_report().total_allocated_bytes
    }

    /// Bytes of the buffers alive now (the pool's idle buffers not included): what a render
    /// holds, without asking the allocator for a report.
    pub fn buffer_bytes_in_use(&self) -> u64 {
        let counts = self.device.buffer_pool.counts();
        counts.total_bytes - counts.idle_bytes
    }

    /// What the buffer pool has done: buffers created and reused, bytes held and idle.
    pub fn buffer_pool_counts(&self) -> PoolCounts {
        self.device.buffer_pool.counts()
    }

    /// Bounds the device memory of all buffers, in use and idle, past which the pool keeps no
    /// idle buffer (a render sets its budget; 0 keeps none), dropping idle ones over it now.
    pub fn keep_buffers_within(&self, bytes: u64) {
        self.device.destroy_buffer_memory(self.device.buffer_pool.set_limit(bytes));
    }

    /// Frees every idle buffer of the pool (another program needs the memory, or a long pause).
    pub fn release_idle_buffers(&self) {
        self.device.destroy_buffer_memory(self.device.buffer_pool.drain_idle());
    }
}
