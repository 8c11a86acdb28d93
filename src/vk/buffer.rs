//! Storage buffers and their memory (gpu-allocator). A [`Buffer`] is a cheap handle; the
//! memory and the `VkBuffer` go back to the device's pool ([`super::pool`]) when the last handle
//! drops — including the handles a [`super::CommandBatch`] keeps until its fence signals.
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::device::Device;
use super::error::VkCall;
use super::pool::BufferMemory;
use super::{CommandBatch, Context};
use crate::{Error, Result};

struct BufferInner {
    device: Arc<Device>,
    /// `Some` until the last handle drops and it goes back to the device's pool.
    memory: Option<BufferMemory>,
    raw: vk::Buffer,
    /// The bytes asked for (bindings and read-backs see these; the memory may hold more).
    size: u64,
    name: String,
    /// Texel views made by [`Buffer::texel_view`]: (format, offset, range, view). They stay
    /// with the memory in the pool, for the next tile that binds the same ranges.
    views: Mutex<Vec<(vk::Format, u64, u64, vk::BufferView)>>,
}

impl Drop for BufferInner {
    fn drop(&mut self) {
        if let Some(mut memory) = self.memory.take() {
            memory.views = std::mem::take(self.views.get_mut().unwrap_or_else(|e| e.into_inner()));
            // The last handle is gone, so no pending submission uses the buffer (batches hold
            // handles until their fence signals): the pool may hand it out again.
            self.device.release_buffer_memory(memory);
        }
    }
}

/// A device buffer usable as a storage buffer, a uniform texel buffer and a transfer
/// source/destination.
#[derive(Clone)]
pub struct Buffer(Arc<BufferInner>);

/// A buffer's contents readable on the host once the batch that recorded their read-back has
/// waited ([`Buffer::readable_in`]): the buffer itself where the host can map it, else space of
/// the batch's read-back arena. The arena's space is handed out again only after every
/// `ReadBack` of it has dropped.
#[derive(Clone)]
pub struct ReadBack {
    pub(super) buffer: Buffer,
    pub(super) offset: u64,
    size: u64,
}

impl ReadBack {
    /// Size in bytes.
    pub fn size(&self) -> u64 {
        self.size
    }

    /// Calls `f` with the contents as `T`s: the mapped memory itself, without a host copy.
    pub fn read_with<T: bytemuck::Pod, R>(&self, ctx: &Context, f: impl FnOnce(&[T]) -> R) -> Result<R> {
        self.buffer.read_range_with(ctx, self.offset, self.size, f)
    }

    /// The contents as `T`s.
    pub fn read<T: bytemuck::Pod>(&self, ctx: &Context) -> Result<Vec<T>> {
        self.read_with(ctx, |items: &[T]| items.to_vec())
    }
}

/// A range of a buffer bound to one descriptor (tiles bind sub-ranges of big buffers).
#[derive(Clone, Copy)]
pub struct Binding<'a> {
    pub buffer: &'a Buffer,
    pub offset: u64,
    pub range: u64,
}

impl Buffer {
    /// Whether the buffer lives on `ctx`'s device (one kept from an earlier render may not).
    pub fn is_on(&self, ctx: &Context) -> bool {
        Arc::ptr_eq(&self.0.device, &ctx.device)
    }

    fn create(ctx: &Context, name: &str, size: u64, location: MemoryLocation) -> Result<Self> {
        Self::create_on(&ctx.device, name, size, size, location)
    }

    /// A buffer of `size` bytes from the device's pool ([`super::pool`]) in memory of at least
    /// `room` bytes (and `size`): memory another buffer of its size class held before, else new.
    /// Its contents are undefined.
    pub(crate) fn create_on(
        device: &Arc<Device>,
        name: &str,
        size: u64,
        room: u64,
        location: MemoryLocation,
    ) -> Result<Self> {
        // Zero-sized buffers are invalid in Vulkan; a 4-byte one keeps callers branch-free.
        let size = size.max(4);
        let mut memory = device.buffer_memory(name, size.max(room), location)?;
        device.set_name(memory.raw, name);
        let views = Mutex::new(std::mem::take(&mut memory.views));
        Ok(Self(Arc::new(BufferInner {
            device: device.clone(),
            raw: memory.raw,
            memory: Some(memory),
            size,
            name: name.to_string(),
            views,
        })))
    }

    /// A view of `range` bytes at `offset` as texels of `format`, for a uniform texel buffer
    /// binding: made once per (format, offset, range), destroyed with the buffer's memory (so it
    /// lives as long as any batch that holds the buffer). The caller checks the device's limits.
    pub(crate) fn texel_view(&self, format: vk::Format, offset: u64, range: u64) -> Result<vk::BufferView> {
        let mut views = self.0.views.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(&(_, _, _, view)) = views.iter().find(|v| (v.0, v.1, v.2) == (format, offset, range)) {
            return Ok(view);
        }
        let info = vk::BufferViewCreateInfo::default().buffer(self.0.raw).format(format).offset(offset).range(range);
        // SAFETY: the buffer is live and was created with UNIFORM_TEXEL_BUFFER usage.
        let view = unsafe { self.0.device.raw.create_buffer_view(&info, None) }.call("vkCreateBufferView")?;
        views.push((format, offset, range, view));
        Ok(view)
    }

    /// A device-local buffer of `size` bytes, zero-filled.
    pub fn zeroed(ctx: &Context, name: &str, size: u64) -> Result<Self> {
        let buffer = Self::create(ctx, name, size, MemoryLocation::GpuOnly)?;
        let mut batch = CommandBatch::new(ctx)?;
        batch.fill_zero(&buffer)?;
        batch.submit_and_wait()?;
        Ok(buffer)
    }

    /// A device-local buffer holding `data`.
    pub fn from_slice<T: bytemuck::Pod>(ctx: &Context, name: &str, data: &[T]) -> Result<Self> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let buffer = Self::create(ctx, name, bytes.len() as u64, MemoryLocation::GpuOnly)?;
        buffer.write(ctx, bytes)?;
        Ok(buffer)
    }

    /// A device-local buffer of `size` bytes with undefined contents, for a buffer that a pass
    /// writes whole before anything reads it: a fill would only cost a pass over the memory
    /// (on a CPU device, a single-threaded memset of freshly mapped pages).
    pub fn uninitialised(ctx: &Context, name: &str, size: u64) -> Result<Self> {
        Self::uninitialised_with_room(ctx, name, size, size)
    }

    /// [`Self::uninitialised`] in memory with room for `room` bytes: a tile's buffer sized for
    /// the largest tile of its frame, so that every tile's buffer of the same role is one size
    /// class of the pool and takes the memory an earlier tile gave back (tiles the frame's
    /// border clips would otherwise each ask for sizes of their own).
    pub fn uninitialised_with_room(ctx: &Context, name: &str, size: u64, room: u64) -> Result<Self> {
        Self::create_on(&ctx.device, name, size, room, MemoryLocation::GpuOnly)
    }

    /// A device-local buffer of `size` bytes, zero-filled by a command recorded into `batch`:
    /// zero for every later command of the batch, without a submission of its own.
    pub fn zeroed_in(ctx: &Context, batch: &mut CommandBatch, name: &str, size: u64) -> Result<Self> {
        Self::zeroed_with_room_in(ctx, batch, name, size, size)
    }

    /// [`Self::zeroed_in`] with room for `room` bytes ([`Self::uninitialised_with_room`]).
    pub fn zeroed_with_room_in(
        ctx: &Context,
        batch: &mut CommandBatch,
        name: &str,
        size: u64,
        room: u64,
    ) -> Result<Self> {
        let buffer = Self::uninitialised_with_room(ctx, name, size, room)?;
        batch.fill_zero(&buffer)?;
        Ok(buffer)
    }

    /// A device-local buffer holding the items of `data` (exactly `len` of them), written
    /// straight into host-visible memory, else through the batch's staging arena and a copy
    /// recorded into `batch` (the batch keeps it across submissions). No submission of its own, and no
    /// host copy of the data beside the mapping.
    pub fn from_iter_in<T: bytemuck::Pod>(
        ctx: &Context,
        batch: &mut CommandBatch,
        name: &str,
        len: usize,
        data: impl IntoIterator<Item = T>,
    ) -> Result<Self> {
        Self::filled_in(ctx, batch, name, len, len, |target: *mut T| {
            let mut written = 0;
            for item in data.into_iter().take(len) {
                // SAFETY: `target` holds `len` items of T (checked by `take`) and
                // `write_unaligned` needs no alignment.
                unsafe { target.add(written).write_unaligned(item) };
                written += 1;
            }
            written
        })
    }

    /// [`Self::from_slice`] recorded into `batch`: no submission of its own (a frame's tables
    /// ride in its first tile's batch).
    pub fn from_slice_in<T: bytemuck::Pod + Sync>(ctx: &Context, batch: &mut CommandBatch, name: &str, data: &[T]) -> Result<Self> {
        Self::from_slices_with_room_in(ctx, batch, name, data.len(), data.len(), [data])
    }

    /// [`Self::from_iter_in`] from contiguous runs (a tile's rows of a frame), each copied with
    /// one memory copy, in memory with room for `room` items
    /// ([`Self::uninitialised_with_room`]): element-wise writes of a tile's inputs into
    /// write-combined staging memory were the largest host cost of large frames on a discrete
    /// GPU.
    pub fn from_slices_with_room_in<'a, T: bytemuck::Pod + Sync>(
        ctx: &Context,
        batch: &mut CommandBatch,
        name: &str,
        len: usize,
        room: usize,
        slices: impl IntoIterator<Item = &'a [T]>,
    ) -> Result<Self> {
        Self::filled_in(ctx, batch, name, len, room, |target: *mut T| copy_runs(target, len, slices))
    }

    /// A device-local buffer of `len` items of T (in memory with room for `room`), filled by
    /// `fill` (given where to write them; it returns how many it wrote), in place where the host
    /// may map it, else in the batch's staging arena with a copy recorded into `batch`.
    fn filled_in<T: bytemuck::Pod>(
        ctx: &Context,
        batch: &mut CommandBatch,
        name: &str,
        len: usize,
        room: usize,
        fill: impl FnOnce(*mut T) -> usize,
    ) -> Result<Self> {
        let item = std::mem::size_of::<T>() as u64;
        let bytes = len as u64 * item;
        let buffer = Self::uninitialised_with_room(ctx, name, bytes, room as u64 * item)?;
        // Device memory the host cannot map (discrete GPUs) is filled from the batch's staging
        // arena, reused by every submission of the batch.
        let (target, offset) = match buffer.host_access() {
            Some(_) => (buffer.clone(), 0),
            None => batch.staging(bytes)?,
        };
        let ptr = target.mapped().ok_or_else(|| Error::internal("staging memory is not host-visible"))?;
        // SAFETY: the mapping holds `bytes` bytes from `offset` (a new buffer, or arena space
        // handed out since the batch's last wait), which no GPU work uses now.
        let written = fill(unsafe { ptr.add(offset as usize) }.cast::<T>());
        if written != len {
            return Err(Error::internal(format!("buffer '{name}': {written} items given, {len} expected")));
        }
        if target.raw() != buffer.raw() {
            batch.copy_region(&target, offset, &buffer, 0, bytes)?;
        }
        Ok(buffer)
    }

    /// This buffer's contents, readable on the host once `batch` has been submitted and waited
    /// for: this buffer itself where its memory is host-visible, else a copy into the batch's
    /// read-back arena recorded into the batch (a plain memory read then).
    pub fn readable_in(&self, batch: &mut CommandBatch) -> Result<ReadBack> {
        if self.host_access().is_some() {
            return Ok(ReadBack { buffer: self.clone(), offset: 0, size: self.size() });
        }
        let (arena, offset) = batch.read_back_space(self.size())?;
        batch.copy_region(self, 0, &arena, offset, self.size())?;
        Ok(ReadBack { buffer: arena, offset, size: self.size() })
    }

    /// Whether a handle besides this one exists (an arena whose space a read-back still holds).
    pub(crate) fn is_shared(&self) -> bool {
        Arc::strong_count(&self.0) > 1
    }

    /// Size in bytes.
    pub fn size(&self) -> u64 {
        self.0.size
    }

    pub fn name(&self) -> &str {
        &self.0.name
    }

    pub(crate) fn raw(&self) -> vk::Buffer {
        self.0.raw
    }

    /// The whole buffer as one binding.
    pub fn all(&self) -> Binding<'_> {
        Binding { buffer: self, offset: 0, range: self.size() }
    }

    /// `range` bytes from `offset` as one binding.
    pub fn range(&self, offset: u64, range: u64) -> Binding<'_> {
        Binding { buffer: self, offset, range }
    }

    /// Host-coherent mapped memory, if the device memory is host-visible (lavapipe, ReBAR,
    /// integrated GPUs): uploads and read-backs then skip the staging copy.
    /// [`Self::mapped`], unless the device moves every transfer through staging memory
    /// ([`super::ContextOptions::staged_transfers`]): whether the host may fill or read this
    /// buffer in place.
    fn host_access(&self) -> Option<*mut u8> {
        self.mapped().filter(|_| !self.0.device.staged_transfers)
    }

    fn mapped(&self) -> Option<*mut u8> {
        let allocation = &self.0.memory.as_ref()?.allocation;
        let coherent = allocation.memory_properties().contains(vk::MemoryPropertyFlags::HOST_COHERENT);
        allocation.mapped_ptr().filter(|_| coherent).map(|p| p.as_ptr().cast::<u8>())
    }

    /// Copies `bytes` to the start of the buffer. Waits: no submission uses the buffer after.
    pub fn write(&self, ctx: &Context, bytes: &[u8]) -> Result<()> {
        self.check_len(bytes.len())?;
        if let Some(ptr) = self.host_access() {
            // SAFETY: the mapping covers `size` bytes, `bytes` fits (checked), and no GPU work
            // uses this buffer now: every batch waits for its fence before returning.
            unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr, bytes.len()) };
            return Ok(());
        }
        let staging = Self::create(ctx, "staging upload", bytes.len() as u64, MemoryLocation::CpuToGpu)?;
        let ptr = staging.mapped().ok_or_else(|| Error::internal("staging memory is not host-visible"))?;
        // SAFETY: the staging mapping holds `bytes.len()` bytes and is not in use.
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr, bytes.len()) };
        let mut batch = CommandBatch::new(ctx)?;
        batch.copy(&staging, self, bytes.len() as u64)?;
        batch.submit_and_wait()
    }

    /// Reads the whole buffer back as `T`s (after the batches that wrote it have waited).
    pub fn read<T: bytemuck::Pod>(&self, ctx: &Context) -> Result<Vec<T>> {
        let count = self.size() as usize / std::mem::size_of::<T>();
        let mut out = vec![T::zeroed(); count];
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut out);
        if let Some(ptr) = self.host_access() {
            // SAFETY: mapped, coherent, `bytes` is within the buffer, and the writing batch has
            // waited on its fence after a shader-write -> host-read barrier.
            unsafe { std::ptr::copy_nonoverlapping(ptr, bytes.as_mut_ptr(), bytes.len()) };
            return Ok(out);
        }
        let staging = Self::create(ctx, "staging read-back", bytes.len() as u64, MemoryLocation::GpuToCpu)?;
        let mut batch = CommandBatch::new(ctx)?;
        batch.copy(self, &staging, bytes.len() as u64)?;
        batch.submit_and_wait()?;
        let ptr = staging.mapped().ok_or_else(|| Error::internal("staging memory is not host-visible"))?;
        // SAFETY: as above, for the staging buffer.
        unsafe { std::ptr::copy_nonoverlapping(ptr, bytes.as_mut_ptr(), bytes.len()) };
        Ok(out)
    }

    /// Calls `f` with the whole buffer as `T`s (after the batches that wrote it have waited):
    /// the mapped memory itself where it is host-visible, else a read-back copy ([`Self::read`]).
    /// A tile's result then goes into the frame without a second copy of it on the host.
    pub fn read_with<T: bytemuck::Pod, R>(&self, ctx: &Context, f: impl FnOnce(&[T]) -> R) -> Result<R> {
        self.read_range_with(ctx, 0, self.size(), f)
    }

    /// [`Self::read_with`] for the `bytes` from `offset`.
    fn read_range_with<T: bytemuck::Pod, R>(
        &self,
        ctx: &Context,
        offset: u64,
        bytes: u64,
        f: impl FnOnce(&[T]) -> R,
    ) -> Result<R> {
        self.check_len((offset + bytes) as usize)?;
        let count = bytes as usize / std::mem::size_of::<T>();
        // SAFETY (the pointer arithmetic): `offset` lies within the mapping (checked above).
        let start = self.mapped().map(|ptr| unsafe { ptr.add(offset as usize) });
        if let Some(ptr) = start.filter(|ptr| (*ptr as usize) % std::mem::align_of::<T>() == 0) {
            // SAFETY: mapped, coherent and aligned for T; `count` Ts lie within the buffer, which
            // `&self` keeps alive while `f` runs; the writing batch has waited on its fence after
            // a shader-write -> host-read barrier, and nothing writes it meanwhile.
            let data = unsafe { std::slice::from_raw_parts(ptr.cast::<T>(), count) };
            return Ok(f(data));
        }
        let all: Vec<u8> = self.read(ctx)?;
        let start = offset as usize;
        Ok(f(&bytemuck::pod_collect_to_vec::<u8, T>(&all[start..start + count * std::mem::size_of::<T>()])))
    }

    fn check_len(&self, len: usize) -> Result<()> {
        if len as u64 > self.size() {
            return Err(Error::internal(format!(
                "{} bytes do not fit buffer '{}' of {} bytes",
                len,
                self.name(),
                self.size()
            )));
        }
        Ok(())
    }
}

/// Fills of at least this many bytes copy their runs on every core: one thread's copy into
/// mapped staging memory was most of the host time of a large tile's upload on a discrete GPU
/// (100 MB for a 1024^2 five-layer tile), and the runs land in disjoint places.
const PARALLEL_FILL_BYTES: usize = 4 << 20;

/// Copies `runs` one after another to `target`, which holds `len` items of T; returns how many
/// items they held, more than `len` (and nothing copied) when they do not fit.
fn copy_runs<'a, T: bytemuck::Pod + Sync>(target: *mut T, len: usize, runs: impl IntoIterator<Item = &'a [T]>) -> usize {
    use rayon::prelude::*;
    let mut placed = Vec::new();
    let mut written = 0;
    for run in runs {
        if written + run.len() > len {
            return len + 1;
        }
        placed.push((written, run));
        written += run.len();
    }
    // The address as an integer: raw pointers do not cross threads, and each run writes its own
    // items.
    let target = target as usize;
    let copy = |&(at, run): &(usize, &[T])| {
        // SAFETY: `target` holds `len` items of T, each run lands at its own `at..at + run.len()`
        // within `len` (checked above), and the sources are distinct host slices. Byte copies
        // need no alignment.
        unsafe {
            std::ptr::copy_nonoverlapping(
                run.as_ptr().cast::<u8>(),
                (target as *mut T).add(at).cast::<u8>(),
                std::mem::size_of_val(run),
            )
        }
    };
    if written * std::mem::size_of::<T>() >= PARALLEL_FILL_BYTES {
        placed.par_iter().for_each(copy);
    } else {
        placed.iter().for_each(copy);
    }
    written
}
