//! Compute pipelines: shader module, a descriptor-set layout of N buffer bindings (set 0,
//! bindings 0..N, each a storage buffer or a uniform texel buffer), and one push-constant
//! range.
use std::sync::Arc;

use ash::vk;

use super::device::Device;
use super::error::VkCall;
use super::Context;
use crate::shaders::ShaderSource;
use crate::{Error, Result};

pub(crate) struct PipelineInner {
    device: Arc<Device>,
    /// Created at the first dispatch (null until then): see [`ComputePipeline::raw`].
    raw: std::sync::Mutex<vk::Pipeline>,
    /// The specialization constants it is compiled with.
    constants: Vec<u32>,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pub(crate) slots: Vec<Slot>,
    pub(crate) push_size: u32,
    pub(crate) shader: ShaderSource,
}

impl Drop for PipelineInner {
    fn drop(&mut self) {
        // SAFETY: the last handle is gone (batches hold one until their fence signals).
        unsafe {
            let raw = *self.raw.get_mut().unwrap_or_else(|poisoned| poisoned.into_inner());
            if raw != vk::Pipeline::null() {
                self.device.raw.destroy_pipeline(raw, None);
            }
            self.device.raw.destroy_pipeline_layout(self.layout, None);
            self.device.raw.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// What one binding of set 0 holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// A storage buffer (`buffer { ... }` in GLSL).
    Storage,
    /// A uniform texel buffer of 32-bit float texels (`uniform samplerBuffer`, read with
    /// `texelFetch`). For hot loads at lane-varying addresses: lavapipe turns such a fetch into
    /// straight-line gathers, a storage-buffer load into a loop over the lanes with a branch
    /// per component; GPUs read either through their caches.
    Texels(TexelFormat),
}

impl Slot {
    /// `base` followed by `more` (`M` = `N` + `K`): the bindings of a pipeline that reads a
    /// few buffers more than another, in a `const`.
    pub const fn concat<const N: usize, const K: usize, const M: usize>(base: [Slot; N], more: [Slot; K]) -> [Slot; M] {
        assert!(M == N + K, "M is N + K");
        let mut slots = [Slot::Storage; M];
        let mut i = 0;
        while i < M {
            slots[i] = if i < N { base[i] } else { more[i - N] };
            i += 1;
        }
        slots
    }
}

/// The texel formats a [`Slot::Texels`] binding may have (every Vulkan device supports them
/// for uniform texel buffers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexelFormat {
    Float,
    Vec2,
    Vec4,
}

impl TexelFormat {
    pub fn format(self) -> vk::Format {
        match self {
            TexelFormat::Float => vk::Format::R32_SFLOAT,
            TexelFormat::Vec2 => vk::Format::R32G32_SFLOAT,
            TexelFormat::Vec4 => vk::Format::R32G32B32A32_SFLOAT,
        }
    }

    pub fn bytes(self) -> u64 {
        match self {
            TexelFormat::Float => 4,
            TexelFormat::Vec2 => 8,
            TexelFormat::Vec4 => 16,
        }
    }
}

/// A compute pipeline for one `glsl/*.comp` entry point.
#[derive(Clone)]
pub struct ComputePipeline(pub(crate) Arc<PipelineInner>);

impl ComputePipeline {
    /// `storage_buffers`: how many storage buffers the shader binds (set 0, bindings 0..n);
    /// `push_size`: `size_of` the push-constant struct (a multiple of 4, at most 128).
    pub fn new(ctx: &Context, shader: &ShaderSource, storage_buffers: u32, push_size: usize) -> Result<Self> {
        Self::with_slots(ctx, shader, &vec![Slot::Storage; storage_buffers as usize], push_size)
    }

    /// A pipeline whose binding i is `slots[i]` (set 0).
    pub fn with_slots(ctx: &Context, shader: &ShaderSource, slots: &[Slot], push_size: usize) -> Result<Self> {
        Self::specialized(ctx, shader, slots, push_size, &[])
    }

    /// [`Self::with_slots`] with the shader's specialization constants `constant_id = i` set to
    /// `constants[i]` (32-bit ints or bools): the driver compiles the shader with them as
    /// literals, so loops over them unroll.
    ///
    /// The context keeps every pipeline it made: asking again for the same shader, slots,
    /// push size and constants returns the same pipeline (no driver work).
    pub fn specialized(ctx: &Context, shader: &ShaderSource, slots: &[Slot], push_size: usize, constants: &[u32]) -> Result<Self> {
        let key = PipelineKey {
            shader: shader.name,
            spirv: (shader.spirv.as_ptr() as usize, shader.spirv.len()),
            slots: slots.to_vec(),
            push_size,
            constants: constants.to_vec(),
        };
        let mut kept = ctx.kept.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let made = kept.iter().filter_map(|object| object.downcast_ref::<MadePipeline>());
        if let Some(found) = made.into_iter().find(|m| m.key == key) {
            return Ok(found.pipeline.clone());
        }
        let pipeline = Self::create(ctx, shader, slots, push_size, constants)?;
        kept.push(Arc::new(MadePipeline { key, pipeline: pipeline.clone() }));
        Ok(pipeline)
    }

    fn create(ctx: &Context, shader: &ShaderSource, slots: &[Slot], push_size: usize, constants: &[u32]) -> Result<Self> {
        let device = &ctx.device;
        check_slots(shader, slots)?;
        let limit = device.info.max_push_constants_size.min(128) as usize;
        if push_size % 4 != 0 || push_size > limit {
            return Err(Error::internal(format!("{}: push constants of {push_size} bytes (must be a multiple of 4, <= {limit})", shader.name)));
        }
        let bindings: Vec<_> = slots
            .iter()
            .enumerate()
            .map(|(b, slot)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b as u32)
                    .descriptor_type(slot.descriptor_type())
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        // SAFETY: valid create info on a live device.
        let set_layout = unsafe { device.raw.create_descriptor_set_layout(&set_info, None) }.call("vkCreateDescriptorSetLayout")?;
        let ranges = [vk::PushConstantRange::default().stage_flags(vk::ShaderStageFlags::COMPUTE).size(push_size as u32)];
        let set_layouts = [set_layout];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if push_size > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        // From here on, dropping `inner` destroys whatever was created.
        let mut inner = PipelineInner {
            device: device.clone(),
            raw: std::sync::Mutex::new(vk::Pipeline::null()),
            constants: constants.to_vec(),
            layout: vk::PipelineLayout::null(),
            set_layout,
            slots: slots.to_vec(),
            push_size: push_size as u32,
            shader: *shader,
        };
        // SAFETY: `set_layout` is live; infos point to locals.
        inner.layout = unsafe { device.raw.create_pipeline_layout(&layout_info, None) }.call("vkCreatePipelineLayout")?;
        Ok(Self(Arc::new(inner)))
    }

    /// The Vulkan pipeline, compiled the first time a dispatch needs it. Why not when it is
    /// made: a method prepares every pipeline any of its paths may dispatch (a disk, a ring, a
    /// kernel image), while a render dispatches a few; a driver that compiles at creation
    /// (lavapipe: 40-110 ms each) would make a one-shot process pay for all of them.
    pub(crate) fn raw(&self) -> Result<vk::Pipeline> {
        let inner = &self.0;
        let mut raw = inner.raw.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if *raw != vk::Pipeline::null() {
            return Ok(*raw);
        }
        let device = &inner.device;
        let module_info = vk::ShaderModuleCreateInfo::default().code(inner.shader.spirv);
        // SAFETY: SPIR-V produced by shaderc at build time.
        let module = unsafe { device.raw.create_shader_module(&module_info, None) }.call("vkCreateShaderModule")?;
        let constants = &inner.constants;
        let entries: Vec<vk::SpecializationMapEntry> = (0..constants.len() as u32)
            .map(|i| vk::SpecializationMapEntry::default().constant_id(i).offset(4 * i).size(4))
            .collect();
        let data: &[u8] = bytemuck::cast_slice(constants);
        let specialization = vk::SpecializationInfo::default().map_entries(&entries).data(data);
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        if !constants.is_empty() {
            stage = stage.specialization_info(&specialization);
        }
        let info = vk::ComputePipelineCreateInfo::default().stage(stage).layout(inner.layout);
        // SAFETY: module, layout and cache are live; the module may be destroyed once the pipeline exists.
        let created = unsafe { device.raw.create_compute_pipelines(device.pipeline_cache.raw, &[info], None) };
        device.pipeline_cache.mark_dirty();
        // SAFETY: no longer needed by anything after pipeline creation.
        unsafe { device.raw.destroy_shader_module(module, None) };
        *raw = created.map_err(|(_, r)| r).call("vkCreateComputePipelines")?[0];
        device.set_name(*raw, inner.shader.name);
        device.check_validation()?;
        Ok(*raw)
    }

    /// Compiles the pipeline now if no dispatch has yet (several may compile on several
    /// threads: each holds its own lock, and the pipeline cache is internally synchronized).
    pub fn compile(&self) -> Result<()> {
        self.raw().map(|_| ())
    }

    /// Whether the pipeline is compiled (by [`Self::compile`] or a dispatch, through any handle
    /// of the context's one).
    pub fn is_compiled(&self) -> bool {
        *self.0.raw.lock().unwrap_or_else(|poisoned| poisoned.into_inner()) != vk::Pipeline::null()
    }

    pub fn shader(&self) -> &ShaderSource {
        &self.0.shader
    }

    /// Whether both are one Vulkan pipeline (the context's kept one, asked for twice).
    pub fn is_same(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }

    /// Workgroup counts covering `extent` invocations (div_ceil by the shader's local size).
    pub fn groups_for(&self, extent: [u32; 3]) -> [u32; 3] {
        let local = self.0.shader.local_size;
        [0, 1, 2].map(|i| extent[i].div_ceil(local[i]).max(1))
    }
}

/// What makes two pipelines the same: [`ComputePipeline::specialized`]'s arguments.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct PipelineKey {
    shader: &'static str,
    /// Where the SPIR-V is (static words): a shader is its code, whatever its name.
    spirv: (usize, usize),
    slots: Vec<Slot>,
    push_size: usize,
    constants: Vec<u32>,
}

/// A pipeline a [`Context`] made, with what it was made from.
pub(crate) struct MadePipeline {
    key: PipelineKey,
    pipeline: ComputePipeline,
}

/// One shader's pipelines, specialized per set of constants ([`ComputePipeline::specialized`])
/// and created on first use: a renderer holds one and asks for the variant a render needs.
pub struct PipelineVariants {
    ctx: Context,
    shader: ShaderSource,
    slots: Vec<Slot>,
    push_size: usize,
    made: std::sync::Mutex<Vec<(Vec<u32>, ComputePipeline)>>,
}

impl PipelineVariants {
    pub fn new(ctx: &Context, shader: &ShaderSource, slots: &[Slot], push_size: usize) -> Result<Self> {
        check_slots(shader, slots)?;
        Ok(Self { ctx: ctx.clone(), shader: *shader, slots: slots.to_vec(), push_size, made: Default::default() })
    }

    /// The pipeline specialized with `constants`, created the first time they are asked for.
    pub fn get(&self, constants: &[u32]) -> Result<ComputePipeline> {
        let mut made = self.made.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some((_, pipeline)) = made.iter().find(|(c, _)| c == constants) {
            return Ok(pipeline.clone());
        }
        let pipeline = ComputePipeline::specialized(&self.ctx, &self.shader, &self.slots, self.push_size, constants)?;
        made.push((constants.to_vec(), pipeline.clone()));
        Ok(pipeline)
    }

    pub fn shader(&self) -> &ShaderSource {
        &self.shader
    }
}

impl Slot {
    pub(crate) fn descriptor_type(self) -> vk::DescriptorType {
        match self {
            Slot::Storage => vk::DescriptorType::STORAGE_BUFFER,
            Slot::Texels(_) => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
        }
    }
}

/// The slots must cover every binding the shader uses, each with the shader's kind: a
/// mismatch is a validation error at best and undefined behaviour without the layers.
fn check_slots(shader: &ShaderSource, slots: &[Slot]) -> Result<()> {
    for b in 0..32usize {
        let (storage, texels) = (shader.storage_bindings >> b & 1 == 1, shader.texel_bindings >> b & 1 == 1);
        let declared = slots.get(b);
        let matches = match declared {
            None => !storage && !texels,
            Some(Slot::Storage) => !texels,
            Some(Slot::Texels(_)) => !storage,
        };
        if !matches {
            let kind = if texels { "a texel buffer" } else { "a storage buffer" };
            return Err(Error::internal(format!("{}: binding {b} is {kind} in the shader, the pipeline declares {declared:?}", shader.name)));
        }
    }
    Ok(())
}
