//! Command recording and submission. A [`CommandBatch`] records dispatches and copies into one
//! command buffer, submits it with a fence, and keeps every buffer, pipeline and descriptor
//! pool it used alive until that fence has signalled. Reusable: after `submit_and_wait` it is
//! reset (command pool and descriptor pools) and records the next batch. Descriptor pools are
//! kept across batches (reset, not destroyed), so a loop of similar batches creates them once.
use std::sync::Arc;

use ash::vk;

use super::arena::StagingArena;
use super::buffer::{Binding, Buffer};
use super::device::Device;
use super::error::VkCall;
use super::pipeline::{ComputePipeline, Slot};
use super::Context;
use crate::{Error, Result};

/// Descriptor sets per pool; a batch adds pools as it needs them (tiles bind many sets).
const SETS_PER_POOL: u32 = 64;
const BUFFERS_PER_SET: u32 = 16;

/// Testing aid: with `LENSBLUR_TEST_FAULT=device-lost` every submission reports
/// `VK_ERROR_DEVICE_LOST` once it has completed, as after a driver reset or a GPU timeout, so
/// tests can prove that a lost device ends a command with an error and writes nothing.
fn injected_device_loss() -> bool {
    static LOST: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *LOST.get_or_init(|| std::env::var("LENSBLUR_TEST_FAULT").is_ok_and(|v| v == "device-lost"))
}

pub struct CommandBatch {
    device: Arc<Device>,
    command_pool: vk::CommandPool,
    command_buffer: vk::CommandBuffer,
    fence: vk::Fence,
    /// Every pool this batch has created; those before `current_pool` are full.
    descriptor_pools: Vec<vk::DescriptorPool>,
    current_pool: usize,
    /// Sets handed out from `descriptor_pools[current_pool]`.
    sets_in_current_pool: u32,
    timestamps: Option<vk::QueryPool>,
    /// Shaders of the dispatches timed in this submission (`LENSBLUR_PROFILE`): query 2 + k
    /// follows dispatch k.
    profiled: Vec<&'static str>,
    last_device_time_ns: Option<f64>,
    in_use_buffers: Vec<Buffer>,
    in_use_pipelines: Vec<ComputePipeline>,
    /// Host-visible staging memory of uploads ([`Self::staging`]) and of read-backs
    /// ([`Self::read_back_space`]).
    staging: StagingArena,
    read_backs: StagingArena,
    recording: bool,
    /// True between a submission and the wait on its fence.
    pending: bool,
    commands: usize,
}

/// Timestamp queries per batch: start and end, plus one per dispatch when profiling.
fn query_count() -> u32 {
    if super::profile::enabled() {
        2 + super::profile::MAX_TIMED_DISPATCHES
    } else {
        2
    }
}

impl CommandBatch {
    pub fn new(ctx: &Context) -> Result<Self> {
        let device = ctx.device.clone();
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(device.queue_family)
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        let mut batch = Self {
            device: device.clone(),
            command_pool: vk::CommandPool::null(),
            command_buffer: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            descriptor_pools: Vec::new(),
            current_pool: 0,
            sets_in_current_pool: 0,
            timestamps: None,
            profiled: Vec::new(),
            last_device_time_ns: None,
            in_use_buffers: Vec::new(),
            in_use_pipelines: Vec::new(),
            staging: StagingArena::uploads(),
            read_backs: StagingArena::read_backs(),
            recording: false,
            pending: false,
            commands: 0,
        };
        // SAFETY (this block): create infos are valid; `Drop` destroys whatever got created.
        unsafe {
            batch.command_pool = device.raw.create_command_pool(&pool_info, None).call("vkCreateCommandPool")?;
            let alloc = vk::CommandBufferAllocateInfo::default()
                .command_pool(batch.command_pool)
                .level(vk::CommandBufferLevel::PRIMARY)
                .command_buffer_count(1);
            batch.command_buffer = device.raw.allocate_command_buffers(&alloc).call("vkAllocateCommandBuffers")?[0];
            batch.fence = device.raw.create_fence(&vk::FenceCreateInfo::default(), None).call("vkCreateFence")?;
            if device.info.timestamp_period_ns.is_some() {
                let info =
                    vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(query_count());
                batch.timestamps = Some(device.raw.create_query_pool(&info, None).call("vkCreateQueryPool")?);
            }
        }
        Ok(batch)
    }

    fn begin_if_needed(&mut self) -> Result<()> {
        if self.recording {
            return Ok(());
        }
        let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: the buffer is not pending (every submission is waited for before reuse).
        unsafe {
            self.device.raw.begin_command_buffer(self.command_buffer, &begin).call("vkBeginCommandBuffer")?;
            if let Some(pool) = self.timestamps {
                self.device.raw.cmd_reset_query_pool(self.command_buffer, pool, 0, query_count());
                self.device.raw.cmd_write_timestamp(self.command_buffer, vk::PipelineStageFlags::TOP_OF_PIPE, pool, 0);
            }
        }
        self.recording = true;
        Ok(())
    }

    /// Makes every earlier shader/transfer write visible to every later command (and the host).
    fn barrier(&mut self) {
        let all_writes = vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE;
        let all_access = vk::AccessFlags::SHADER_READ
            | vk::AccessFlags::SHADER_WRITE
            | vk::AccessFlags::TRANSFER_READ
            | vk::AccessFlags::TRANSFER_WRITE
            | vk::AccessFlags::HOST_READ;
        let stages = vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER;
        let barrier = vk::MemoryBarrier::default().src_access_mask(all_writes).dst_access_mask(all_access);
        // SAFETY: recording is active.
        unsafe {
            self.device.raw.cmd_pipeline_barrier(
                self.command_buffer,
                stages,
                stages | vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            )
        };
    }

    fn allocate_set(&mut self, pipeline: &ComputePipeline) -> Result<vk::DescriptorSet> {
        if self.sets_in_current_pool >= SETS_PER_POOL {
            self.current_pool += 1;
            self.sets_in_current_pool = 0;
        }
        if self.current_pool == self.descriptor_pools.len() {
            let sizes = [vk::DescriptorType::STORAGE_BUFFER, vk::DescriptorType::UNIFORM_TEXEL_BUFFER]
                .map(|ty| vk::DescriptorPoolSize::default().ty(ty).descriptor_count(SETS_PER_POOL * BUFFERS_PER_SET));
            let info = vk::DescriptorPoolCreateInfo::default().max_sets(SETS_PER_POOL).pool_sizes(&sizes);
            // SAFETY: valid create info; destroyed in `Drop`.
            let pool = unsafe { self.device.raw.create_descriptor_pool(&info, None) }.call("vkCreateDescriptorPool")?;
            self.descriptor_pools.push(pool);
        }
        let layouts = [pipeline.0.set_layout];
        let pool = self.descriptor_pools[self.current_pool];
        let info = vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts);
        // SAFETY: the pool has room for one more set of at most BUFFERS_PER_SET buffers.
        let set = unsafe { self.device.raw.allocate_descriptor_sets(&info) }.call("vkAllocateDescriptorSets")?[0];
        self.sets_in_current_pool += 1;
        Ok(set)
    }

    /// Records one dispatch of `pipeline` over `groups` workgroups with `bindings` at set 0
    /// (binding i = `bindings[i]`) and `push` as push constants, followed by a barrier.
    pub fn dispatch<P: bytemuck::Pod>(
        &mut self,
        pipeline: &ComputePipeline,
        bindings: &[Binding<'_>],
        push: &P,
        groups: [u32; 3],
    ) -> Result<()> {
        self.record_dispatch(pipeline, bindings, push, groups)?;
        self.barrier();
        self.time_dispatch(pipeline.shader().name);
        Ok(())
    }

    /// [`Self::dispatch`] without the barrier after it (the tests prove that synchronization
    /// validation reports what a missing barrier would let race).
    fn record_dispatch<P: bytemuck::Pod>(
        &mut self,
        pipeline: &ComputePipeline,
        bindings: &[Binding<'_>],
        push: &P,
        groups: [u32; 3],
    ) -> Result<()> {
        let name = pipeline.shader().name;
        let slots = &pipeline.0.slots;
        if bindings.len() != slots.len() || bindings.len() > BUFFERS_PER_SET as usize {
            return Err(Error::internal(format!(
                "{name}: {} buffers bound, pipeline declares {}",
                bindings.len(),
                slots.len()
            )));
        }
        if std::mem::size_of::<P>() != pipeline.0.push_size as usize {
            return Err(Error::internal(format!(
                "{name}: push constants of {} bytes, pipeline declares {}",
                std::mem::size_of::<P>(),
                pipeline.0.push_size
            )));
        }
        let limits = &self.device.info;
        let max_range = u64::from(limits.max_storage_buffer_range);
        // One view per binding; null where the slot is a storage buffer.
        let mut texel_views = Vec::with_capacity(bindings.len());
        for (b, slot) in bindings.iter().zip(slots) {
            if b.offset + b.range > b.buffer.size() {
                return Err(Error::internal(format!(
                    "{name}: binding of '{}' ({} bytes at {}) exceeds the buffer ({} bytes)",
                    b.buffer.name(),
                    b.range,
                    b.offset,
                    b.buffer.size()
                )));
            }
            match slot {
                Slot::Storage if b.range > max_range => {
                    return Err(Error::internal(format!(
                        "{name}: binding of '{}' ({} bytes) exceeds the device's storage range of {max_range} bytes",
                        b.buffer.name(),
                        b.range
                    )));
                }
                Slot::Storage => texel_views.push([vk::BufferView::null()]),
                Slot::Texels(format) => {
                    let texels = b.range / format.bytes();
                    let alignment = limits.min_texel_buffer_offset_alignment.max(1);
                    if texels > u64::from(limits.max_texel_buffer_elements) || b.offset % alignment != 0 {
                        return Err(Error::internal(format!(
                            "{name}: texel binding of '{}' ({texels} texels at byte {}) exceeds the device's {} texels or its offset alignment of {alignment} bytes",
                            b.buffer.name(), b.offset, limits.max_texel_buffer_elements
                        )));
                    }
                    // A whole number of texels: a trailing partial one would not be a texel.
                    texel_views.push([b.buffer.texel_view(format.format(), b.offset, texels * format.bytes())?]);
                }
            }
        }
        if (0..3).any(|i| groups[i] > limits.max_workgroup_count[i]) {
            return Err(Error::internal(format!(
                "{name}: {groups:?} workgroups exceed the device limit {:?}",
                limits.max_workgroup_count
            )));
        }
        self.begin_if_needed()?;
        let set = self.allocate_set(pipeline)?;
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = bindings
            .iter()
            .map(|b| [vk::DescriptorBufferInfo::default().buffer(b.buffer.raw()).offset(b.offset).range(b.range)])
            .collect();
        let writes: Vec<vk::WriteDescriptorSet> = (0..bindings.len())
            .map(|i| {
                let write = vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(i as u32)
                    .descriptor_type(slots[i].descriptor_type());
                match slots[i] {
                    Slot::Storage => write.buffer_info(&infos[i]),
                    Slot::Texels(_) => write.texel_buffer_view(&texel_views[i]),
                }
            })
            .collect();
        let raw_pipeline = pipeline.raw()?;
        let cmd = self.command_buffer;
        // SAFETY: the set is fresh (not in use), buffers and pipeline are live and kept alive
        // by `in_use_*` until the fence signals; sizes were checked above.
        unsafe {
            self.device.raw.update_descriptor_sets(&writes, &[]);
            self.device.raw.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, raw_pipeline);
            self.device.raw.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                pipeline.0.layout,
                0,
                &[set],
                &[],
            );
            if pipeline.0.push_size > 0 {
                self.device.raw.cmd_push_constants(
                    cmd,
                    pipeline.0.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(push),
                );
            }
            self.device.raw.cmd_dispatch(cmd, groups[0], groups[1], groups[2]);
        }
        self.in_use_pipelines.push(pipeline.clone());
        self.in_use_buffers.extend(bindings.iter().map(|b| b.buffer.clone()));
        self.commands += 1;
        Ok(())
    }

    /// Records a copy of the first `bytes` bytes of `src` into `dst`, followed by a barrier.
    pub fn copy(&mut self, src: &Buffer, dst: &Buffer, bytes: u64) -> Result<()> {
        self.copy_region(src, 0, dst, 0, bytes)
    }

    /// Records copying `bytes` from `src` at `src_offset` to `dst` at `dst_offset`.
    pub fn copy_region(
        &mut self,
        src: &Buffer,
        src_offset: u64,
        dst: &Buffer,
        dst_offset: u64,
        bytes: u64,
    ) -> Result<()> {
        if src_offset + bytes > src.size() || dst_offset + bytes > dst.size() {
            return Err(Error::internal(format!(
                "copy of {bytes} bytes from '{}' at {src_offset} to '{}' at {dst_offset} out of bounds",
                src.name(),
                dst.name()
            )));
        }
        self.begin_if_needed()?;
        let region = vk::BufferCopy::default().src_offset(src_offset).dst_offset(dst_offset).size(bytes);
        // SAFETY: both buffers are live, kept alive below, and the region is in bounds.
        unsafe { self.device.raw.cmd_copy_buffer(self.command_buffer, src.raw(), dst.raw(), &[region]) };
        self.barrier();
        self.in_use_buffers.extend([src.clone(), dst.clone()]);
        self.commands += 1;
        Ok(())
    }

    /// `bytes` of host-visible staging memory for an upload recorded into this batch: the arena
    /// and the offset of the space ([`super::arena`]: reused by every submission of the batch).
    pub(crate) fn staging(&mut self, bytes: u64) -> Result<(Buffer, u64)> {
        self.staging.space(&self.device, bytes)
    }

    /// `bytes` of host-readable memory for a read-back recorded into this batch: the arena and
    /// the offset of the space, readable once the batch has waited.
    pub(crate) fn read_back_space(&mut self, bytes: u64) -> Result<(Buffer, u64)> {
        self.read_backs.space(&self.device, bytes)
    }

    /// Host-visible staging bytes this batch holds (its upload arenas).
    pub fn staging_bytes(&self) -> u64 {
        self.staging.bytes()
    }

    /// Host-readable bytes this batch holds for read-backs (its read-back arenas).
    pub fn read_back_bytes(&self) -> u64 {
        self.read_backs.bytes()
    }

    /// Records zero-filling the whole buffer.
    pub fn fill_zero(&mut self, buffer: &Buffer) -> Result<()> {
        self.begin_if_needed()?;
        // SAFETY: the buffer is live and kept alive below; WHOLE_SIZE rounds down to 4 bytes.
        unsafe { self.device.raw.cmd_fill_buffer(self.command_buffer, buffer.raw(), 0, vk::WHOLE_SIZE, 0) };
        self.barrier();
        self.in_use_buffers.push(buffer.clone());
        self.commands += 1;
        Ok(())
    }

    /// Descriptor pools this batch holds (created as batches needed them, kept across resets).
    pub fn descriptor_pool_count(&self) -> usize {
        self.descriptor_pools.len()
    }

    /// Commands recorded since the last submission.
    pub fn len(&self) -> usize {
        self.commands
    }

    pub fn is_empty(&self) -> bool {
        self.commands == 0
    }

    /// Submits what was recorded, waits for it, checks validation, and resets for reuse.
    pub fn submit_and_wait(&mut self) -> Result<()> {
        if !self.recording {
            return Ok(());
        }
        let cmd = self.command_buffer;
        // SAFETY: recording is active; ending it and submitting with our unsignalled fence.
        unsafe {
            if let Some(pool) = self.timestamps {
                self.device.raw.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, pool, 1);
            }
            self.device.raw.end_command_buffer(cmd).call("vkEndCommandBuffer")?;
            self.recording = false;
            let buffers = [cmd];
            let submit = vk::SubmitInfo::default().command_buffers(&buffers);
            let queue = self.device.queue();
            self.device.raw.queue_submit(*queue, &[submit], self.fence).call("vkQueueSubmit")?;
        }
        self.pending = true;
        // SAFETY: the fence belongs to this device and was submitted just above.
        unsafe { self.device.raw.wait_for_fences(&[self.fence], true, u64::MAX) }.call("vkWaitForFences")?;
        self.pending = false;
        if injected_device_loss() {
            // The work did complete, so everything is still safe to tear down.
            return Err(Error::Vulkan { call: "vkWaitForFences", result: vk::Result::ERROR_DEVICE_LOST });
        }
        self.last_device_time_ns = self.read_timestamps();
        self.add_profiled_times();
        self.reset()?;
        self.device.check_validation()
    }

    fn read_timestamps(&self) -> Option<f64> {
        let pool = self.timestamps?;
        let period = self.device.info.timestamp_period_ns? as f64;
        let mut ticks = [0u64; 2];
        // SAFETY: both queries were written by the submission that has completed.
        unsafe { self.device.raw.get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64) }.ok()?;
        Some(ticks[1].saturating_sub(ticks[0]) as f64 * period)
    }

    /// With `LENSBLUR_PROFILE`, a timestamp after the dispatch just recorded (of `shader`).
    fn time_dispatch(&mut self, shader: &'static str) {
        let Some(pool) = self.timestamps.filter(|_| super::profile::enabled()) else { return };
        let index = 2 + self.profiled.len() as u32;
        if index < query_count() {
            // SAFETY: recording is active (a dispatch was just recorded) and the query was
            // reset at the start of this command buffer.
            unsafe {
                self.device.raw.cmd_write_timestamp(
                    self.command_buffer,
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    pool,
                    index,
                );
            }
            self.profiled.push(shader);
        }
    }

    /// Adds the completed submission's per-dispatch times to the profile.
    fn add_profiled_times(&mut self) {
        let shaders = std::mem::take(&mut self.profiled);
        let (Some(pool), Some(period)) = (self.timestamps, self.device.info.timestamp_period_ns) else { return };
        if shaders.is_empty() {
            return;
        }
        let mut ticks = vec![0u64; 2 + shaders.len()];
        // SAFETY: every query read was written by the submission that has completed.
        let read =
            unsafe { self.device.raw.get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64) };
        if read.is_err() {
            return;
        }
        let mut previous = ticks[0];
        for (shader, &tick) in shaders.iter().zip(&ticks[2..]) {
            super::profile::add(shader, tick.saturating_sub(previous) as f64 * f64::from(period));
            previous = tick;
        }
    }

    /// Device time of the last submission (timestamp queries), if the queue supports them.
    pub fn last_device_time_ns(&self) -> Option<f64> {
        self.last_device_time_ns
    }

    fn reset(&mut self) -> Result<()> {
        self.staging.reset();
        self.read_backs.reset();
        // SAFETY: the fence has signalled, so nothing recorded is pending any more.
        unsafe {
            self.device.raw.reset_fences(&[self.fence]).call("vkResetFences")?;
            self.device
                .raw
                .reset_command_pool(self.command_pool, vk::CommandPoolResetFlags::empty())
                .call("vkResetCommandPool")?;
            // Only the pools this batch used hold sets; later ones are still empty.
            for &pool in &self.descriptor_pools[..self.descriptor_pools.len().min(self.current_pool + 1)] {
                self.device
                    .raw
                    .reset_descriptor_pool(pool, vk::DescriptorPoolResetFlags::empty())
                    .call("vkResetDescriptorPool")?;
            }
        }
        // Every pool is kept for the next batch: a loop of similar batches creates them once.
        self.current_pool = 0;
        self.sets_in_current_pool = 0;
        self.in_use_buffers.clear();
        self.in_use_pipelines.clear();
        self.commands = 0;
        Ok(())
    }
}

impl Drop for CommandBatch {
    fn drop(&mut self) {
        // SAFETY: if a submission may still run (its wait failed), wait before destroying
        // anything it uses; then destroy in reverse order of creation. Null handles are no-ops.
        unsafe {
            if self.pending {
                let _ = self.device.raw.wait_for_fences(&[self.fence], true, u64::MAX);
            }
            if let Some(pool) = self.timestamps {
                self.device.raw.destroy_query_pool(pool, None);
            }
            for &pool in &self.descriptor_pools {
                self.device.raw.destroy_descriptor_pool(pool, None);
            }
            self.device.raw.destroy_fence(self.fence, None);
            self.device.raw.destroy_command_pool(self.command_pool, None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shaders;
    use crate::vk::arena::{MIN_STAGING, STAGING_ALIGN};
    use crate::vk::ContextOptions;

    /// Staging space comes from one arena, handed out anew after each wait; a submission that
    /// outgrows it gets a second arena, and after the wait one arena of the total size serves.
    #[test]
    fn staging_arenas_are_reused_after_each_wait_and_merged_when_outgrown() {
        let options = ContextOptions { validation: true, ..ContextOptions::from_env() };
        let ctx = Context::new(&options)
            .unwrap_or_else(|e| panic!("this test needs a Vulkan device with validation layers: {e}"));
        let target = Buffer::zeroed(&ctx, "target", 2048).unwrap();
        let mut batch = CommandBatch::new(&ctx).unwrap();
        let (first, offset) = batch.staging(1000).unwrap();
        let (same, next) = batch.staging(1000).unwrap();
        assert_eq!((offset, same.raw(), next), (0, first.raw(), STAGING_ALIGN * 4), "aligned space in one arena");
        let (second, at) = batch.staging(MIN_STAGING).unwrap();
        assert!(second.raw() != first.raw() && at == 0, "past the first arena: a second one");
        let total = batch.staging_bytes();
        assert_eq!(total, first.size() + second.size());
        batch.copy_region(&first, next, &target, 0, 1000).unwrap();
        batch.submit_and_wait().unwrap();
        drop((first, same, second));
        let (merged, offset) = batch.staging(16).unwrap();
        assert_eq!(
            (merged.size(), offset, batch.staging_bytes()),
            (total, 0, total),
            "one arena of the total after the wait"
        );
        batch.copy_region(&merged, 0, &target, 0, 16).unwrap();
        batch.submit_and_wait().unwrap();
        let (again, offset) = batch.staging(16).unwrap();
        assert_eq!((again.raw(), offset), (merged.raw(), 0), "the one arena is kept and its space handed out anew");
        drop((merged, again, batch, target));
        ctx.finish().unwrap();
    }

    /// Read-back space is handed out again after a wait only once the read-backs of the last
    /// submission have dropped: one still held keeps its bytes, and the next submission reads
    /// back into another arena.
    #[test]
    fn read_back_arenas_are_reused_only_once_their_read_backs_are_dropped() {
        let options = ContextOptions { validation: true, staged_transfers: true, ..ContextOptions::from_env() };
        let ctx = Context::new(&options)
            .unwrap_or_else(|e| panic!("this test needs a Vulkan device with validation layers: {e}"));
        let data = [1u32, 2, 3, 4];
        let source = Buffer::from_slice(&ctx, "source", &data).unwrap();
        let mut batch = CommandBatch::new(&ctx).unwrap();
        let (first, second) = (source.readable_in(&mut batch).unwrap(), source.readable_in(&mut batch).unwrap());
        assert!(first.buffer.raw() != source.raw(), "staged: a copy into the read-back arena");
        assert_eq!((first.offset, second.buffer.raw(), second.offset), (0, first.buffer.raw(), STAGING_ALIGN));
        batch.submit_and_wait().unwrap();
        let third = source.readable_in(&mut batch).unwrap();
        assert!(third.buffer.raw() != first.buffer.raw(), "the first arena's read-backs are still held");
        batch.submit_and_wait().unwrap();
        for read_back in [&first, &second, &third] {
            assert_eq!(read_back.read::<u32>(&ctx).unwrap(), data);
        }
        let third_arena = third.buffer.raw();
        drop((first, second, third));
        let fourth = source.readable_in(&mut batch).unwrap();
        assert_eq!((fourth.buffer.raw(), fourth.offset), (third_arena, 0), "nothing holds the arena: reused");
        assert_eq!(batch.read_back_bytes(), MIN_STAGING);
        batch.submit_and_wait().unwrap();
        assert_eq!(fourth.read::<u32>(&ctx).unwrap(), data);
        drop((fourth, batch, source));
        ctx.finish().unwrap();
    }

    /// What the second command of a pair does to the buffer the first one wrote or read.
    #[derive(Clone, Copy, Debug)]
    enum Pair {
        /// Dispatch writes `a`; dispatch reads and writes `a` (a pass consuming the previous
        /// pass's output in place).
        ReadAfterWrite,
        /// Dispatch reads `a`; dispatch reads and writes `a`.
        WriteAfterRead,
        /// Fill zeroes `a`; dispatch writes `a` (an accumulator cleared before its pass).
        WriteAfterFill,
    }

    /// Records one pair on buffers `a` and `b` with or without the barrier between them and
    /// returns what submission and teardown reported.
    fn record_pair(pair: Pair, barrier: bool) -> Result<()> {
        let options = ContextOptions { validation: true, ..ContextOptions::from_env() };
        let ctx = Context::new(&options)
            .unwrap_or_else(|e| panic!("this test needs a Vulkan device with validation layers: {e}"));
        // disk_blur.comp: binding 0 read (texels), 1 read (kernel), 2 written; push {width,
        // height, half_extent, pad}.
        let pipeline =
            ComputePipeline::with_slots(&ctx, &shaders::DISK_BLUR, &crate::render::disk::DISK_BLUR_SLOTS, 16)?;
        let (width, height) = (8u32, 8u32);
        let pixels = vec![[1.0f32; 4]; (width * height) as usize];
        let (a, b) = (Buffer::from_slice(&ctx, "a", &pixels)?, Buffer::from_slice(&ctx, "b", &pixels)?);
        let kernel = Buffer::from_slice(&ctx, "kernel", &[1.0f32])?;
        let push = [width as i32, height as i32, 0, 0];
        let groups = pipeline.groups_for([width, height, 1]);
        let mut batch = CommandBatch::new(&ctx)?;
        let (first, second) = match pair {
            Pair::ReadAfterWrite => ([Some(&b), Some(&a)], [&a, &a]),
            Pair::WriteAfterRead => ([Some(&a), Some(&b)], [&a, &a]),
            Pair::WriteAfterFill => ([None, None], [&b, &a]),
        };
        match first {
            [Some(source), Some(result)] => {
                batch.record_dispatch(&pipeline, &[source.all(), kernel.all(), result.all()], &push, groups)?
            }
            _ => {
                batch.begin_if_needed()?;
                // SAFETY: recording is active; `a` is live and kept alive by `in_use_buffers`.
                unsafe { batch.device.raw.cmd_fill_buffer(batch.command_buffer, a.raw(), 0, vk::WHOLE_SIZE, 0) };
                batch.in_use_buffers.push(a.clone());
            }
        }
        if barrier {
            batch.barrier();
        }
        batch.record_dispatch(&pipeline, &[second[0].all(), kernel.all(), second[1].all()], &push, groups)?;
        batch.barrier();
        let submitted = batch.submit_and_wait();
        drop(batch);
        submitted.and(ctx.finish())
    }

    const PAIRS: [(Pair, &str); 3] = [
        (Pair::ReadAfterWrite, "SYNC-HAZARD-READ-AFTER-WRITE"),
        (Pair::WriteAfterRead, "SYNC-HAZARD-WRITE-AFTER-READ"),
        (Pair::WriteAfterFill, "SYNC-HAZARD-WRITE-AFTER-WRITE"),
    ];

    /// Proves `LENSBLUR_VALIDATION=1` really runs synchronization validation. Not covered: two
    /// dispatches that only write one buffer. Layer 1.3.239 (Debian 12) reports no
    /// WRITE-AFTER-WRITE between two dispatches' storage writes (measured: the same pair as a
    /// fill then a dispatch, or a dispatch then a fill, is reported), so that pair cannot be a test.
    #[test]
    fn synchronization_validation_reports_each_missing_barrier() {
        for (pair, hazard) in PAIRS {
            match record_pair(pair, false) {
                Err(Error::Validation { first, .. }) => {
                    assert!(first.contains(hazard), "{pair:?}: another message: {first}")
                }
                other => panic!("{pair:?} without a barrier was not reported: {other:?}"),
            }
        }
    }

    #[test]
    fn the_barrier_between_commands_makes_each_pair_clean() {
        for (pair, _) in PAIRS {
            if let Err(e) = record_pair(pair, true) {
                panic!("{pair:?} with the barrier reported: {e}");
            }
        }
    }
}
