//! GPU host code of multiview synthesis: uploads what [`super::prepare`] builds (pyramids,
//! height fields, culling masks, lens samples) once for the frame, dispatches
//! `glsl/multiview_trace.comp` over frame tiles ([`crate::render::tiling`]), reads each back.
//! The inputs stay whole: cone tracing reads mip levels whose texels span any extent, so a
//! tile's reach is the frame; tiling bounds each dispatch's time and the output's memory.
use super::prepare::Prepared;
use super::MultiviewParams;
use crate::image::Image;
use crate::render::tiling::{rect_push, render_image_tiles, Footprint, FrameTiling, RenderOptions, RenderStats};
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
    occupancy_words: i32,
    pad: [i32; 2],
    k: f32,
    focus: f32,
    cone: f32,
    pad3: f32,
    /// The tile's core ([`rect_push`]); inputs are the whole frame's.
    core: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<MultiviewPush>() == 80);

/// Multiview synthesis on the GPU.
pub struct Multiview {
    ctx: Context,
    pipeline: ComputePipeline,
}

impl Multiview {
    pub fn new(ctx: &Context) -> Result<Self> {
        let slots = [
            Slot::Texels(TexelFormat::Vec4),
            Slot::Texels(TexelFormat::Float),
            Slot::Storage,
            Slot::Storage,
            Slot::Storage,
            Slot::Storage,
            Slot::Storage,
        ];
        let pipeline =
            ComputePipeline::with_slots(ctx, &shaders::MULTIVIEW_TRACE, &slots, std::mem::size_of::<MultiviewPush>())?;
        Ok(Self { ctx: ctx.clone(), pipeline })
    }

    pub fn run(&self, stack: &LayerStack, lens: &Lens, params: &MultiviewParams) -> Result<Image> {
        Ok(self.run_with(stack, lens, params, &RenderOptions::default())?.0)
    }

    /// [`Self::run`] on frame tiles cut as `options` says; the same pixels for every tile size.
    pub fn run_with(
        &self,
        stack: &LayerStack,
        lens: &Lens,
        params: &MultiviewParams,
        options: &RenderOptions,
    ) -> Result<(Image, RenderStats)> {
        let ctx = &self.ctx;
        let pr = Prepared::new(stack, lens, params)?;
        // The pyramids and height fields (most of a render's memory) are built straight into
        // the device buffers: no host copy of them exists beside the device's.
        let mut upload = CommandBatch::new(ctx)?;
        let pyramid =
            Buffer::from_iter_in(ctx, &mut upload, "multiview pyramid", pr.layers * pr.pyramid_len, pr.pyramid_texels(stack))?;
        let heights = Buffer::from_iter_in(ctx, &mut upload, "multiview heights", pr.layers * pr.plane, pr.height_texels(stack))?;
        upload.submit_and_wait()?;
        let occupancy = Buffer::from_slice(ctx, "multiview occupancy", &pr.occupancy)?;
        let bounds = Buffer::from_slice(ctx, "multiview bounds", &pr.bounds)?;
        let levels = Buffer::from_slice(ctx, "multiview levels", &pr.levels)?;
        let samples = Buffer::from_slice(ctx, "multiview lens samples", &pr.samples.data)?;
        // Work bound: per lens sample and layer, the intersection's steps and one cone sample.
        let work = (pr.samples.slots * pr.layers) as u64 * (u64::from(pr.steps) + 1);
        let mut frame = FrameTiling::new(pr.width, pr.height, pr.layers, 1).with_work(work);
        // The frame's inputs are held on the device for the whole render, beside the tiles.
        frame.host_bytes += [&pyramid, &heights, &occupancy].iter().map(|b| b.size()).sum::<u64>();
        // A tile holds only its core's result.
        let footprint = |tile| Footprint::per_pixel(&frame, tile, 0, 0, 16, 16);
        let push = |core| MultiviewPush {
            width: pr.width as i32,
            height: pr.height as i32,
            layers: pr.layers as i32,
            level_count: pr.levels.len() as i32,
            slots: pr.samples.slots as i32,
            patterns: pr.samples.patterns as i32,
            steps: pr.steps as i32,
            cull: i32::from(pr.cull),
            pyramid_len: pr.pyramid_len as i32,
            occupancy_words: pr.occupancy_words as i32,
            pad: [0; 2],
            k: pr.k,
            focus: pr.focus,
            cone: pr.cone,
            pad3: 0.0,
            core: rect_push(core),
        };
        render_image_tiles(
            ctx,
            &frame,
            options,
            footprint,
            |_| 0,
            |batch, core, _| {
                // The shader writes every core pixel.
                let result = Buffer::uninitialised(ctx, "multiview result", core.area() as u64 * 16)?;
                let bindings = [
                    pyramid.all(),
                    heights.all(),
                    occupancy.all(),
                    bounds.all(),
                    levels.all(),
                    samples.all(),
                    result.all(),
                ];
                let groups = self.pipeline.groups_for([core.width() as u32, core.height() as u32, 1]);
                batch.dispatch(&self.pipeline, &bindings, &push(core), groups)?;
                result.readable_in(ctx, batch)
            },
        )
    }
}
