//! GPU host code of Virtual DSLR: on frame tiles ([`crate::render::tiler`]), uploads each
//! tile's read rect of the image, the edited disparity map, the true disparity and the mixed
//! edge pixels, with the lens sample sets shared by every tile, dispatches
//! `glsl/vdslr_trace.comp` over its core, reads back.
use super::{prepare, VdslrParams};
use crate::image::Image;
use crate::render::tiler::{
    crop, crop_rows, rect_push, render_image_tiles, Footprint, FrameTiling, RenderOptions, RenderStats,
};
use crate::render::Lens;
use crate::shaders;
use crate::vk::{Buffer, ComputePipeline, Context, Slot, TexelFormat};
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
    /// The tile's core and read rects ([`rect_push`]).
    core: [i32; 4],
    read: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<VdslrPush>() == 80);

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
        let pipeline =
            ComputePipeline::with_slots(ctx, &shaders::VDSLR_TRACE, &slots, std::mem::size_of::<VdslrPush>())?;
        Ok(Self { ctx: ctx.clone(), pipeline })
    }

    pub fn run(&self, image: &Image, disparity: &[f32], lens: &Lens, params: &VdslrParams) -> Result<Image> {
        Ok(self.run_with(image, disparity, lens, params, &RenderOptions::default())?.0)
    }

    /// [`Self::run`] on frame tiles cut as `options` says; the same pixels for every tile size.
    pub fn run_with(
        &self,
        image: &Image,
        disparity: &[f32],
        lens: &Lens,
        params: &VdslrParams,
        options: &RenderOptions,
    ) -> Result<(Image, RenderStats)> {
        let (ctx, width) = (&self.ctx, image.width);
        let prepared = prepare(image, disparity, lens, params)?;
        // Every search step reads the pixel nearest p + u K s, with s the start s_max or a
        // relative disparity of the map, and u a lens sample (either sign: the mirrored search):
        // per axis at most K max|u| max|s| away, + 1 for the rounding to the nearest pixel and
        // + 1 for f32 products rounding past an integer.
        let s_reach = prepared.relative.iter().fold(prepared.s_max.abs(), |m, s| m.max(s.abs()));
        let u_reach = prepared.samples.data.iter().fold(0.0f32, |m, s| m.max(s[0].abs()).max(s[1].abs()));
        let halo = (lens.coc.k_px.abs() * u_reach * s_reach).ceil() as usize + 2;
        // Work bound: two searches (the mirrored one) of iterations + 1 steps per lens sample.
        let work = prepared.samples.slots as u64 * 2 * (u64::from(params.iterations) + 1);
        let frame = FrameTiling::new(width, image.height, 1, 1).with_work(work);
        let samples = Buffer::from_slice(ctx, "vdslr lens samples", &prepared.samples.data)?;
        let (sigma, white) = params.highlight.map_or((1.0, 1.0), |h| (h.sigma, h.white));
        // RGBA and two disparities per read pixel, the edge record and RGBA per core pixel;
        // RGBA is the largest binding. A mixed edge pixel reads its 3x3 neighbours: within the
        // halo.
        let footprint = |tile| Footprint::per_pixel(&frame, tile, halo, 24, 32, 16);
        render_image_tiles(
            ctx,
            &frame,
            options,
            footprint,
            |_| halo,
            |batch, core, read, room| {
                let source = Buffer::from_slices_with_room_in(
                    ctx,
                    batch,
                    "vdslr image",
                    read.area(),
                    room.read,
                    crop_rows(&image.pixels, width, read),
                )?;
                let relative = crop(&prepared.relative, width, read);
                let relative = Buffer::from_iter_in(ctx, batch, "vdslr relative disparity", read.area(), relative)?;
                let true_disparity = Buffer::from_slices_with_room_in(
                    ctx,
                    batch,
                    "vdslr disparity",
                    read.area(),
                    room.read,
                    crop_rows(disparity, width, read),
                )?;
                // The core's edge records, classified now: a whole frame's would outweigh the image.
                let edge_records = prepared.edges_in(image, disparity, lens.coc.k_px, core);
                let edges =
                    Buffer::from_iter_in(ctx, batch, "vdslr mixed edges", core.area(), edge_records)?;
                // The shader writes every core pixel.
                let (bytes, room) = (core.area() as u64 * 16, room.core as u64 * 16);
                let result = Buffer::uninitialised_with_room(ctx, "vdslr result", bytes, room)?;
                let push = VdslrPush {
                    width: width as i32,
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
                    core: rect_push(core),
                    read: rect_push(read),
                };
                let bindings =
                    [source.all(), relative.all(), true_disparity.all(), samples.all(), edges.all(), result.all()];
                let groups = self.pipeline.groups_for([core.width() as u32, core.height() as u32, 1]);
                batch.dispatch(&self.pipeline, &bindings, &push, groups)?;
                result.readable_in(batch)
            },
        )
    }
}
