//! Device memory kept across tiles and renders. Every [`super::Buffer`] takes its `VkBuffer` and
//! memory from its device's pool and gives them back when its last handle drops (a batch holds
//! its handles until its fence has signalled, so nothing pending uses what comes back). A
//! returned buffer waits, idle, for the next request of its size class and memory location: the
//! tiles of a frame (whose buffers have room for the largest tile,
//! [`super::Buffer::uninitialised_with_room`]), and the frames of a shot or a session, all ask
//! for the same few sizes.
//!
//! Allocating every tile's intermediates anew cost a large share of a render's host time: on a
//! GPU each allocation is a driver call and often a new memory block, and on a CPU device
//! (lavapipe) the new memory's every page is faulted in again by the first pass that writes it.
//!
//! Bounded: idle buffers are kept only while all the pool's buffers, in use and idle, stay
//! within the limit the tiler sets to each render's device budget (0, keep nothing, until a
//! render sets one). Released under pressure: a new allocation first drops the oldest idle
//! buffers that would push the total past the limit, and one the driver refuses is retried once
//! after dropping every idle buffer. Everything left is destroyed with the device.
use std::collections::HashMap;
use std::sync::Mutex;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme, Allocator};
use gpu_allocator::MemoryLocation;

use super::device::Device;
use super::error::VkCall;
use crate::{Error, Result};

/// Classes per octave of size: a request is rounded up to the next class, so tiles whose halos
/// the frame's border clips (a little smaller than the others) share their buffers, at most
/// 1/8 more memory than asked for.
const CLASSES_PER_OCTAVE: u64 = 8;
/// The smallest class: lens tables and search windows are a few hundred bytes.
const MIN_CLASS: u64 = 256;
/// Texel views a buffer keeps while idle: each (format, offset, range) a request bound; more
/// come from requests of other sizes in the class, and are remade cheaply when needed.
const MAX_KEPT_VIEWS: usize = 16;

/// The bytes a request of `bytes` is allocated with: the next class boundary.
pub(crate) fn size_class(bytes: u64) -> u64 {
    let bytes = bytes.max(MIN_CLASS);
    let step = bytes.next_power_of_two() / (2 * CLASSES_PER_OCTAVE);
    bytes.next_multiple_of(step.max(1))
}

/// A `VkBuffer` of one size class with its bound memory and texel views: what a buffer handle
/// owns while in use and the pool keeps while idle.
pub(crate) struct BufferMemory {
    pub raw: vk::Buffer,
    pub allocation: Allocation,
    pub location: MemoryLocation,
    /// The class size the buffer was created with (requests of up to this many bytes fit).
    pub capacity: u64,
    /// (format, offset, range, view).
    pub views: Vec<(vk::Format, u64, u64, vk::BufferView)>,
}

impl BufferMemory {
    /// Device bytes the buffer holds (its allocation: the class size, or more for alignment).
    pub fn bytes(&self) -> u64 {
        self.allocation.size()
    }

    /// Destroys the views and the buffer and frees the memory. The caller guarantees that no
    /// pending submission uses them (the last handle is gone, or the device is idle).
    pub fn destroy(self, device: &ash::Device, allocator: &mut Allocator) {
        // SAFETY: per the caller, nothing pending uses the views or the buffer.
        unsafe {
            for (_, _, _, view) in self.views {
                device.destroy_buffer_view(view, None);
            }
            let _ = allocator.free(self.allocation);
            device.destroy_buffer(self.raw, None);
        }
    }
}

/// Counts of what the pool has done since the device opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PoolCounts {
    /// Buffers created (pool misses), and requests served with an idle buffer.
    pub created: u64,
    pub reused: u64,
    /// Bytes of the pool's buffers now, in use and idle, and of the idle ones.
    pub total_bytes: u64,
    pub idle_bytes: u64,
    /// The most bytes the pool's buffers held at once since the device opened: a render's
    /// peak device memory for its buffers (what the GPU kit reports per case).
    pub peak_bytes: u64,
}

#[derive(Default)]
struct PoolState {
    /// Idle buffers by (class size, location); each list oldest first.
    idle: HashMap<(u64, MemoryLocation), Vec<(u64, BufferMemory)>>,
    /// Return order of idle buffers, for dropping the oldest first.
    clock: u64,
    limit_bytes: u64,
    counts: PoolCounts,
}

impl PoolState {
    /// Takes idle buffers, oldest first, until the pool's total plus `incoming` fits the limit.
    fn evict_for(&mut self, incoming: u64) -> Vec<BufferMemory> {
        let mut evicted = Vec::new();
        while self.counts.total_bytes + incoming > self.limit_bytes && self.counts.idle_bytes > 0 {
            let oldest = self
                .idle
                .iter()
                .filter_map(|(key, list)| list.first().map(|(stamp, _)| (*stamp, *key)))
                .min_by_key(|(stamp, _)| *stamp)
                .map(|(_, key)| key);
            let Some(key) = oldest else { break };
            let list = self.idle.get_mut(&key).expect("the key was just found");
            let (_, memory) = list.remove(0);
            if list.is_empty() {
                self.idle.remove(&key);
            }
            self.counts.idle_bytes -= memory.bytes();
            self.counts.total_bytes -= memory.bytes();
            evicted.push(memory);
        }
        evicted
    }
}

#[derive(Default)]
pub(crate) struct BufferPool {
    state: Mutex<PoolState>,
}

impl BufferPool {
    fn state(&self) -> std::sync::MutexGuard<'_, PoolState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// An idle buffer of `capacity` bytes in `location`, if one waits.
    pub fn take(&self, capacity: u64, location: MemoryLocation) -> Option<BufferMemory> {
        let mut state = self.state();
        let list = state.idle.get_mut(&(capacity, location))?;
        // The most recently returned: its pages are the likeliest to be warm.
        let (_, memory) = list.pop()?;
        if list.is_empty() {
            state.idle.remove(&(capacity, location));
        }
        state.counts.idle_bytes -= memory.bytes();
        state.counts.reused += 1;
        Some(memory)
    }

    /// Before creating a buffer of `bytes`: the idle buffers to destroy so that the pool stays
    /// within its limit with it. The caller destroys them (outside this lock).
    pub fn make_room(&self, bytes: u64) -> Vec<BufferMemory> {
        self.state().evict_for(bytes)
    }

    /// Counts a buffer just created for a request.
    pub fn created(&self, memory: &BufferMemory) {
        let mut state = self.state();
        state.counts.created += 1;
        state.counts.total_bytes += memory.bytes();
        state.counts.peak_bytes = state.counts.peak_bytes.max(state.counts.total_bytes);
    }

    /// Takes back a buffer whose last handle dropped: kept idle if the pool's limit allows,
    /// else returned for the caller to destroy.
    pub fn give_back(&self, memory: BufferMemory) -> Option<BufferMemory> {
        let mut state = self.state();
        if state.counts.total_bytes > state.limit_bytes {
            state.counts.total_bytes -= memory.bytes();
            return Some(memory);
        }
        state.clock += 1;
        let stamp = state.clock;
        state.counts.idle_bytes += memory.bytes();
        state.idle.entry((memory.capacity, memory.location)).or_default().push((stamp, memory));
        None
    }

    /// Sets the bytes the pool's buffers may hold, in use and idle, and returns the idle
    /// buffers past it (oldest first) for the caller to destroy.
    pub fn set_limit(&self, bytes: u64) -> Vec<BufferMemory> {
        let mut state = self.state();
        state.limit_bytes = bytes;
        state.evict_for(0)
    }

    /// Every idle buffer, for the caller to destroy (memory pressure, or the device closing).
    pub fn drain_idle(&self) -> Vec<BufferMemory> {
        let mut state = self.state();
        let idle: Vec<BufferMemory> = state.idle.drain().flat_map(|(_, list)| list).map(|(_, m)| m).collect();
        let bytes: u64 = idle.iter().map(BufferMemory::bytes).sum();
        state.counts.idle_bytes -= bytes;
        state.counts.total_bytes -= bytes;
        idle
    }

    pub fn counts(&self) -> PoolCounts {
        self.state().counts
    }
}

/// Usage of every buffer: one kind of buffer serves every binding, copy and read-back.
const USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::STORAGE_BUFFER.as_raw()
        | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER.as_raw()
        | vk::BufferUsageFlags::TRANSFER_SRC.as_raw()
        | vk::BufferUsageFlags::TRANSFER_DST.as_raw(),
);

impl Device {
    /// A buffer of at least `bytes` in `location`: an idle one of its size class, else a new one
    /// (after dropping idle buffers past the pool's limit; if the driver refuses it, once more
    /// after dropping every idle buffer).
    pub(crate) fn buffer_memory(&self, name: &str, bytes: u64, location: MemoryLocation) -> Result<BufferMemory> {
        let capacity = size_class(bytes);
        if let Some(memory) = self.buffer_pool.take(capacity, location) {
            return Ok(memory);
        }
        self.destroy_buffer_memory(self.buffer_pool.make_room(capacity));
        let memory = match self.create_buffer_memory(name, capacity, location) {
            Err(error) if self.buffer_pool.counts().idle_bytes > 0 => {
                log::debug!("allocating '{name}' failed ({error}); retrying without the idle buffers");
                self.destroy_buffer_memory(self.buffer_pool.drain_idle());
                self.create_buffer_memory(name, capacity, location)?
            }
            result => result?,
        };
        self.buffer_pool.created(&memory);
        Ok(memory)
    }

    fn create_buffer_memory(&self, name: &str, capacity: u64, location: MemoryLocation) -> Result<BufferMemory> {
        let info = vk::BufferCreateInfo::default().size(capacity).usage(USAGE).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info on a live device.
        let raw = unsafe { self.raw.create_buffer(&info, None) }.call("vkCreateBuffer")?;
        // SAFETY: `raw` was just created on this device.
        let requirements = unsafe { self.raw.get_buffer_memory_requirements(raw) };
        let desc = AllocationCreateDesc {
            name,
            requirements,
            location,
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        };
        let allocation = match self.allocator().allocate(&desc) {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the buffer has no memory and was never used.
                unsafe { self.raw.destroy_buffer(raw, None) };
                return Err(Error::Allocation(e));
            }
        };
        // SAFETY: a live allocation of this device, bound exactly once; it satisfies the
        // buffer's requirements.
        let bound = unsafe { self.raw.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) };
        let memory = BufferMemory { raw, allocation, location, capacity, views: Vec::new() };
        if let Err(e) = bound.call("vkBindBufferMemory") {
            self.destroy_buffer_memory(vec![memory]);
            return Err(e);
        }
        Ok(memory)
    }

    /// Takes back the memory of a buffer whose last handle dropped (so no pending submission
    /// uses it): idle in the pool, or destroyed past the pool's limit.
    pub(crate) fn release_buffer_memory(&self, mut memory: BufferMemory) {
        if memory.views.len() > MAX_KEPT_VIEWS {
            for (_, _, _, view) in memory.views.drain(..) {
                // SAFETY: the buffer's last handle is gone, so nothing pending uses the view.
                unsafe { self.raw.destroy_buffer_view(view, None) };
            }
        }
        if let Some(rejected) = self.buffer_pool.give_back(memory) {
            self.destroy_buffer_memory(vec![rejected]);
        }
    }

    /// Destroys buffers no handle and no pending submission uses (idle ones, or rejected).
    pub(crate) fn destroy_buffer_memory(&self, memories: Vec<BufferMemory>) {
        if memories.is_empty() {
            return;
        }
        let mut allocator = self.allocator();
        for memory in memories {
            memory.destroy(&self.raw, &mut allocator);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_classes_waste_at_most_an_eighth_and_are_their_own_class() {
        assert_eq!(size_class(1), MIN_CLASS);
        assert_eq!(size_class(1024), 1024);
        assert_eq!(size_class(1025), 1024 + 128);
        for bytes in [300u64, 4097, 1 << 20, (1 << 20) + 1, 12_345_678, 3 << 30] {
            let class = size_class(bytes);
            assert!(class >= bytes && (class - bytes) * 8 <= bytes, "{bytes} -> {class}");
            assert_eq!(size_class(class), class, "{bytes} -> {class}");
        }
    }
}
