//! Vulkan plumbing on raw `ash`: the only module with Vulkan calls and `unsafe`.
//!
//! Ownership follows screen-13: every object is an RAII value holding an `Arc` of the device;
//! `Drop` frees memory, then the handle. A [`CommandBatch`] keeps alive everything its
//! submission uses until its fence signals; the device waits idle and drops its allocator
//! before `vkDestroyDevice`, and the instance (with its validation messenger) goes last.
//!
//! ```no_run
//! # fn main() -> lensblur::Result<()> {
//! use lensblur::vk::{Buffer, CommandBatch, ComputePipeline, Context, Slot, TexelFormat};
//! let ctx = Context::from_env()?;
//! # let (shader, push, n) = (lensblur::shaders::DISK_BLUR, [0i32; 4], 1u32);
//! // Binding kinds as the shader declares them (checked against its SPIR-V).
//! let slots = [Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float), Slot::Storage];
//! let pipeline = ComputePipeline::with_slots(&ctx, &shader, &slots, std::mem::size_of_val(&push))?;
//! let (a, b, c) = (Buffer::from_slice(&ctx, "a", &[0f32; 4])?, Buffer::zeroed(&ctx, "b", 16)?, Buffer::zeroed(&ctx, "c", 16)?);
//! let mut batch = CommandBatch::new(&ctx)?;
//! batch.dispatch(&pipeline, &[a.all(), b.all(), c.all()], &push, pipeline.groups_for([n, 1, 1]))?;
//! batch.submit_and_wait()?;
//! let result: Vec<f32> = c.read(&ctx)?;
//! # Ok(()) }
//! ```
mod arena;
mod buffer;
mod command;
mod device;
mod error;
mod instance;
mod pipeline;
mod pipeline_cache;
mod pool;
pub mod profile;
pub mod validation;

pub use buffer::{Binding, Buffer, ReadBack};
pub use command::CommandBatch;
pub use device::{list_devices, Context, ContextOptions, DeviceInfo, MemoryBudget};
pub use pipeline::{ComputePipeline, PipelineVariants, Slot, TexelFormat};
pub use pool::PoolCounts;
