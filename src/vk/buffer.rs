//! Storage buffers and their memory (gpu-allocator). A [`Buffer`] is a cheap handle; the
//! memory and the `VkBuffer` are freed when the last handle drops — including the handles a
//! [`super::CommandBatch`] keeps until its fence signals.
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::device::Device;
use super::error::VkCall;
use super::{CommandBatch, Context};
use crate::{Error, Result};

struct BufferInner {
    device: Arc<Device>,
    raw: vk::Buffer,
    allocation: Option<Allocation>,
    size: u64,
    name: String,
    /// Texel views made by [`Buffer::texel_view`]: (format, offset, range, view).
    views: Mutex<Vec<(vk::Format, u64, u64, vk::BufferView)>>,
}

impl Drop for BufferInner {
    fn drop(&mut self) {
        for (_, _, _, view) in self.views.get_mut().unwrap_or_else(|e| e.into_inner()).drain(..) {
            // SAFETY: the last handle is gone, so no pending submission uses the view.
            unsafe { self.device.raw.destroy_buffer_view(view, None) };
        }
        if let Some(allocation) = self.allocation.take() {
            let _ = self.device.allocator().free(allocation);
        }
        // SAFETY: the last handle is gone, so no pending submission references the buffer
        // (batches hold handles until their fence signals); its memory was freed just above.
        unsafe { self.device.raw.destroy_buffer(self.raw, None) };
    }
}

/// A device buffer usable as a storage buffer, a uniform texel buffer and a transfer
/// source/destination.
#[derive(Clone)]
pub struct Buffer(Arc<BufferInner>);

/// A range of a buffer bound to one descriptor (tiles bind sub-ranges of big buffers).
#[derive(Clone, Copy)]
pub struct Binding<'a> {
    pub buffer: &'a Buffer,
    pub offset: u64,
    pub range: u64,
}

const USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::STORAGE_BUFFER.as_raw()
        | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER.as_raw()
        | vk::BufferUsageFlags::TRANSFER_SRC.as_raw()
        | vk::BufferUsageFlags::TRANSFER_DST.as_raw(),
);

impl Buffer {
    fn create(ctx: &Context, name: &str, size: u64, location: MemoryLocation) -> Result<Self> {
        Self::create_on(&ctx.device, name, size, location)
    }

    pub(crate) fn create_on(device: &Arc<Device>, name: &str, size: u64, location: MemoryLocation) -> Result<Self> {
        // Zero-sized buffers are invalid in Vulkan; a 4-byte one keeps callers branch-free.
        let size = size.max(4);
        let info = vk::BufferCreateInfo::default().size(size).usage(USAGE).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info on a live device.
        let raw = unsafe { device.raw.create_buffer(&info, None) }.call("vkCreateBuffer")?;
        // SAFETY: `raw` was just created on this device.
        let requirements = unsafe { device.raw.get_buffer_memory_requirements(raw) };
        let desc = AllocationCreateDesc {
            name,
            requirements,
            location,
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        };
        let allocation = match device.allocator().allocate(&desc) {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the buffer has no memory and was never used.
                unsafe { device.raw.destroy_buffer(raw, None) };
                return Err(Error::Allocation(e));
            }
        };
        // SAFETY: a live allocation of this device; read before it moves into the handle.
        let (memory, offset) = unsafe { (allocation.memory(), allocation.offset()) };
        // From here on, dropping `inner` frees the memory and destroys the buffer.
        let inner = BufferInner {
            device: device.clone(),
            raw,
            allocation: Some(allocation),
            size,
            name: name.to_string(),
            views: Mutex::new(Vec::new()),
        };
        // SAFETY: the allocation satisfies the buffer's requirements and is bound exactly once.
        unsafe { device.raw.bind_buffer_memory(raw, memory, offset) }.call("vkBindBufferMemory")?;
        device.set_name(raw, name);
        Ok(Self(Arc::new(inner)))
    }

    /// A view of `range` bytes at `offset` as texels of `format`, for a uniform texel buffer
    /// binding: made once per (format, offset, range), destroyed with the buffer (so it lives
    /// as long as any batch that holds the buffer). The caller checks the device's limits.
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
        Self::create(ctx, name, size, MemoryLocation::GpuOnly)
    }

    /// A device-local buffer of `size` bytes, zero-filled by a command recorded into `batch`:
    /// zero for every later command of the batch, without a submission of its own.
    pub fn zeroed_in(ctx: &Context, batch: &mut CommandBatch, name: &str, size: u64) -> Result<Self> {
        let buffer = Self::create(ctx, name, size, MemoryLocation::GpuOnly)?;
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
        Self::filled_in(ctx, batch, name, len, |target: *mut T| {
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

    /// [`Self::from_iter_in`] from contiguous runs (a tile's rows of a frame), each copied with
    /// one memory copy: element-wise writes of a tile's inputs into write-combined staging
    /// memory were the largest host cost of large frames on a discrete GPU.
    pub fn from_slices_in<'a, T: bytemuck::Pod>(
        ctx: &Context,
        batch: &mut CommandBatch,
        name: &str,
        len: usize,
        slices: impl IntoIterator<Item = &'a [T]>,
    ) -> Result<Self> {
        Self::filled_in(ctx, batch, name, len, |target: *mut T| {
            let mut written = 0;
            for slice in slices {
                let count = slice.len().min(len - written);
                // SAFETY: `target` holds `len` items of T and `written + count <= len`; the
                // source is a distinct host slice. Byte copies need no alignment.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        slice.as_ptr().cast::<u8>(),
                        target.add(written).cast::<u8>(),
                        count * std::mem::size_of::<T>(),
                    )
                };
                written += count;
                if count < slice.len() {
                    // More items than `len`: report one more, which fails the length check.
                    return written + 1;
                }
            }
            written
        })
    }

    /// A device-local buffer of `len` items of T, filled by `fill` (given where to write them;
    /// it returns how many it wrote), in place where the host may map it, else in the batch's
    /// staging arena with a copy recorded into `batch`.
    fn filled_in<T: bytemuck::Pod>(
        ctx: &Context,
        batch: &mut CommandBatch,
        name: &str,
        len: usize,
        fill: impl FnOnce(*mut T) -> usize,
    ) -> Result<Self> {
        let bytes = (len * std::mem::size_of::<T>()) as u64;
        let buffer = Self::create(ctx, name, bytes, MemoryLocation::GpuOnly)?;
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

    /// A host-readable buffer that holds this buffer's contents once `batch` has been submitted
    /// and waited for: this buffer itself where its memory is host-visible, else a staging copy
    /// recorded into the batch. Read it with [`Buffer::read`] (a plain memory copy then).
    pub fn readable_in(&self, ctx: &Context, batch: &mut CommandBatch) -> Result<Self> {
        if self.host_access().is_some() {
            return Ok(self.clone());
        }
        let staging = Self::create(ctx, "staging read-back", self.size(), MemoryLocation::GpuToCpu)?;
        batch.copy(self, &staging, self.size())?;
        Ok(staging)
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
        let allocation = self.0.allocation.as_ref()?;
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
        let aligned = |ptr: &*mut u8| (*ptr as usize) % std::mem::align_of::<T>() == 0;
        if let Some(ptr) = self.mapped().filter(aligned) {
            let count = self.size() as usize / std::mem::size_of::<T>();
            // SAFETY: mapped, coherent and aligned for T; `count` Ts lie within the buffer, which
            // `&self` keeps alive while `f` runs; the writing batch has waited on its fence after
            // a shader-write -> host-read barrier, and nothing writes it meanwhile.
            let data = unsafe { std::slice::from_raw_parts(ptr.cast::<T>(), count) };
            return Ok(f(data));
        }
        Ok(f(&self.read::<T>(ctx)?))
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
