//! GPU host code of multiview synthesis: uploads what [`super::prepare`] built (pyramids,
//! height fields, culling masks, lens samples), dispatches `glsl/multiview_trace.comp` once,
//! reads back.
use super::prepare::Prepared;
use super::MultiviewParams;
use crate::image::Image;
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context, Slot, TexelFormat};
use crate::Result;

/// Push constants of `glsl/multiview_trace.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct MultiviewPush {
    width: i32,
    height: i32,
    layers: i32,
    level_count: i32,
    slots: i32,
    patterns: i32,
    steps: i32,
    cull: i32,
    pyramid_len: i32,
    pad: [i32; 3],
    k: f32,
    focus: f32,
    cone: f32,
    pad3: f32,
}
const _: () = assert!(std::mem::size_of::<MultiviewPush>() == 64);

/// Multiview synthesis on the GPU.
pub struct Multiview {
    ctx: Context,
    pipeline: ComputePipeline,
}

impl Multiview {
    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::with_slots(ctx, &shaders::MULTIVIEW_TRACE, &[Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float), Slot::Storage, Slot::Storage, Slot::Storage, Slot::Storage, Slot::Storage], std::mem::size_of::<MultiviewPush>())?;
        Ok(Self { ctx: ctx.clone(), pipeline })
    }

    pub fn run(&self, stack: &LayerStack, lens: &Lens, params: &MultiviewParams) -> Result<Image> {
        let ctx = &self.ctx;
        let pr = Prepared::new(stack, lens, params)?;
        let pyramid = Buffer::from_slice(ctx, "multiview pyramid", &pr.pyramid)?;
        let heights = Buffer::from_slice(ctx, "multiview heights", &pr.heights)?;
        let occupancy = Buffer::from_slice(ctx, "multiview occupancy", &pr.occupancy)?;
        let bounds = Buffer::from_slice(ctx, "multiview bounds", &pr.bounds)?;
        let levels = Buffer::from_slice(ctx, "multiview levels", &pr.levels)?;
        let samples = Buffer::from_slice(ctx, "multiview lens samples", &pr.samples.data)?;
        let result = Buffer::zeroed(ctx, "multiview result", (pr.plane * std::mem::size_of::<[f32; 4]>()) as u64)?;
        let push = MultiviewPush {
            width: pr.width as i32,
            height: pr.height as i32,
            layers: pr.layers as i32,
            level_count: pr.levels.len() as i32,
            slots: pr.samples.slots as i32,
            patterns: pr.samples.patterns as i32,
            steps: pr.steps as i32,
            cull: i32::from(pr.cull),
            pyramid_len: pr.pyramid_len as i32,
            pad: [0; 3],
            k: pr.k,
            focus: pr.focus,
            cone: pr.cone,
            pad3: 0.0,
        };
        let bindings = [pyramid.all(), heights.all(), occupancy.all(), bounds.all(), levels.all(), samples.all(), result.all()];
        let groups = self.pipeline.groups_for([pr.width as u32, pr.height as u32, 1]);
        let mut batch = CommandBatch::new(ctx)?;
        batch.dispatch(&self.pipeline, &bindings, &push, groups)?;
        batch.submit_and_wait()?;
        let pixels: Vec<[f32; 4]> = result.read(ctx)?;
        Ok(Image { width: pr.width, height: pr.height, pixels })
    }
}
