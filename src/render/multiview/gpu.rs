//! GPU host code of multiview synthesis: dispatches `glsl/multiview_trace.comp` over frame
//! tiles ([`crate::render::tiler`]) and reads each back. Each tile gets its own window of the
//! layers ([`super::prepare::Window`]: its rays' reach, aligned to the top mip level they
//! read) with the height fields and pyramids over it, built straight into device memory; only
//! the culling masks (a bit a pixel) and the lens samples are the frame's. So the tiler bounds
//! the inputs' memory too, and a tile computes exactly what the whole frame computes there.
use super::prepare::{Prepared, Window};
use super::MultiviewParams;
use crate::image::Image;
use crate::render::tiler::{rect_push, render_image_tiles, Footprint, FrameTiling, RenderOptions, RenderStats};
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::vk::{Buffer, ComputePipeline, Context, Slot, TexelFormat};
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
    /// The tile's core ([`rect_push`]).
    core: [i32; 4],
    /// The tile's window: the rect its height fields and pyramids cover.
    window: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<MultiviewPush>() == 96);

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
        let occupancy = Buffer::from_slice(ctx, "multiview occupancy", &pr.occupancy)?;
        let bounds = Buffer::from_slice(ctx, "multiview bounds", &pr.bounds)?;
        let samples = Buffer::from_slice(ctx, "multiview lens samples", &pr.samples.data)?;
        // Work bound: per lens sample and layer, the intersection's steps and one cone sample.
        let work = (pr.samples.slots * pr.layers) as u64 * (u64::from(pr.steps) + 1);
        let mut frame = FrameTiling::new(pr.width, pr.height, pr.layers, 1).with_work(work);
        // The culling masks are held on the device for the whole render, beside the tiles.
        frame.host_bytes += occupancy.size();
        // A tile holds its window's height fields and pyramids (every layer) and its core's
        // result; a window reaches at most `Prepared::window_halo` past its core.
        let footprint = |tile: usize| {
            let window = pr.largest_window(tile);
            let layers = pr.layers as u64;
            let pyramid = layers * window.pyramid_len as u64 * 16;
            let heights = layers * window.rect.area() as u64 * 4;
            let result = (tile.min(pr.width) * tile.min(pr.height)) as u64 * 16;
            Footprint { largest_binding: pyramid.max(heights).max(result), total: pyramid + heights + result }
        };
        let push = |core, window: &Window| MultiviewPush {
            width: pr.width as i32,
            height: pr.height as i32,
            layers: pr.layers as i32,
            level_count: pr.level_count as i32,
            slots: pr.samples.slots as i32,
            patterns: pr.samples.patterns as i32,
            steps: pr.steps as i32,
            cull: i32::from(pr.cull),
            pyramid_len: window.pyramid_len as i32,
            occupancy_words: pr.occupancy_words as i32,
            pad: [0; 2],
            k: pr.k,
            focus: pr.focus,
            cone: pr.cone,
            pad3: 0.0,
            core: rect_push(core),
            window: rect_push(window.rect),
        };
        render_image_tiles(
            ctx,
            &frame,
            options,
            footprint,
            // What a tile reads is its window, not the service's read rect.
            |_| 0,
            |batch, core, _, room| {
                let window = pr.window(core);
                let pyramid_len = pr.layers * window.pyramid_len;
                let upper = pr.window_upper_levels(stack, &window);
                let pyramids = pr.window_pyramids(stack, &window, &upper);
                let pyramid =
                    Buffer::from_slices_with_room_in(ctx, batch, "multiview pyramid", pyramid_len, pyramid_len, pyramids)?;
                let heights = Buffer::from_slice_in(ctx, batch, "multiview heights", &pr.window_heights(stack, &window))?;
                let levels =
                    Buffer::from_iter_in(ctx, batch, "multiview levels", window.levels.len(), window.levels.iter().copied())?;
                // The shader writes every core pixel.
                let (bytes, room) = (core.area() as u64 * 16, room.core as u64 * 16);
                let result = Buffer::uninitialised_with_room(ctx, "multiview result", bytes, room)?;
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
                batch.dispatch(&self.pipeline, &bindings, &push(core, &window), groups)?;
                result.readable_in(batch)
            },
        )
    }
}
