//! GPU host code of Virtual DSLR: uploads the image, the edited disparity map and the lens
//! sample sets and the mixed edge pixels, dispatches `glsl/vdslr_trace.comp` once, reads back.
use super::{prepare, VdslrParams};
use crate::image::Image;
use crate::render::Lens;
use crate::shaders;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context, Slot, TexelFormat};
use crate::Result;

/// Push constants of `glsl/vdslr_trace.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct VdslrPush {
    width: i32,
    height: i32,
    iterations: i32,
    slots: i32,
    patterns: i32,
    bleeding_guard: i32,
    highlight: i32,
    pad: i32,
    k: f32,
    s_max: f32,
    sigma: f32,
    white: f32,
}
const _: () = assert!(std::mem::size_of::<VdslrPush>() == 48);

/// Virtual DSLR on the GPU.
pub struct Vdslr {
    ctx: Context,
    pipeline: ComputePipeline,
}

impl Vdslr {
    pub fn new(ctx: &Context) -> Result<Self> {
        // image, relative, disparity, samples, edges, result: the bindings of vdslr_trace.comp.
        let (vec4, float) = (Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float));
        let slots = [vec4, float, float, Slot::Storage, vec4, Slot::Storage];
        let pipeline = ComputePipeline::with_slots(ctx, &shaders::VDSLR_TRACE, &slots, std::mem::size_of::<VdslrPush>())?;
        Ok(Self { ctx: ctx.clone(), pipeline })
    }

    pub fn run(&self, image: &Image, disparity: &[f32], lens: &Lens, params: &VdslrParams) -> Result<Image> {
        let ctx = &self.ctx;
        let prepared = prepare(image, disparity, lens, params)?;
        let source = Buffer::from_slice(ctx, "vdslr image", &image.pixels)?;
        let relative = Buffer::from_slice(ctx, "vdslr relative disparity", &prepared.relative)?;
        let true_disparity = Buffer::from_slice(ctx, "vdslr disparity", disparity)?;
        let samples = Buffer::from_slice(ctx, "vdslr lens samples", &prepared.samples.data)?;
        let edges = Buffer::from_slice(ctx, "vdslr mixed edges", &prepared.edges)?;
        let result = Buffer::zeroed(ctx, "vdslr result", std::mem::size_of_val(image.pixels.as_slice()) as u64)?;
        let (sigma, white) = params.highlight.map_or((1.0, 1.0), |h| (h.sigma, h.white));
        let push = VdslrPush {
            width: image.width as i32,
            height: image.height as i32,
            iterations: params.iterations as i32,
            slots: prepared.samples.slots as i32,
            patterns: prepared.samples.patterns as i32,
            bleeding_guard: i32::from(params.bleeding_guard),
            highlight: i32::from(params.highlight.is_some()),
            pad: 0,
            k: lens.coc.k_px,
            s_max: prepared.s_max,
            sigma,
            white,
        };
        let bindings = [source.all(), relative.all(), true_disparity.all(), samples.all(), edges.all(), result.all()];
        let groups = self.pipeline.groups_for([image.width as u32, image.height as u32, 1]);
        let mut batch = CommandBatch::new(ctx)?;
        batch.dispatch(&self.pipeline, &bindings, &push, groups)?;
        batch.submit_and_wait()?;
        let pixels: Vec<[f32; 4]> = result.read(ctx)?;
        Ok(Image { width: image.width, height: image.height, pixels })
    }
}
