//! GPU host code of the Dr.Bokeh forward renderer: uploads a stack, runs the four passes of
//! `glsl/drbokeh_*.comp` in one command batch, reads the composite back. The CPU reference of
//! the same passes is [`super::cpu`]; `Params` (validation, lens, area table, push constants)
//! is shared with it, so the two differ only in f32 vs f64 arithmetic.
use super::{Model, Params};
use crate::image::Image;
use crate::render::Lens;
use crate::shaders;
use crate::stack::LayerStack;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context};
use crate::Result;

/// Bytes of one `vec2` / `vec4` in std430.
const VEC2: u64 = 8;
const VEC4: u64 = 16;

/// The Dr.Bokeh pipelines on one device; build once, render many stacks.
pub struct DrBokehGpu {
    ctx: Context,
    tile_bounds: ComputePipeline,
    tile_window: ComputePipeline,
    layer: ComputePipeline,
    composite: ComputePipeline,
}

/// What one render measured on the device.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderStats {
    /// Device time of the passes (timestamp queries), if the queue supports them.
    pub device_ns: Option<f64>,
}

impl DrBokehGpu {
    pub fn new(ctx: &Context) -> Result<Self> {
        let push = std::mem::size_of::<super::DrBokehPush>();
        Ok(Self {
            ctx: ctx.clone(),
            tile_bounds: ComputePipeline::new(ctx, &shaders::DRBOKEH_TILE_BOUNDS, 3, push)?,
            tile_window: ComputePipeline::new(ctx, &shaders::DRBOKEH_TILE_WINDOW, 2, push)?,
            layer: ComputePipeline::new(ctx, &shaders::DRBOKEH_LAYER, 7, push)?,
            composite: ComputePipeline::new(ctx, &shaders::DRBOKEH_COMPOSITE, 3, push)?,
        })
    }

    pub fn context(&self) -> &Context {
        &self.ctx
    }

    /// Renders `stack` through `lens`: premultiplied linear RGBA, HDR unclamped.
    pub fn render(&self, stack: &LayerStack, lens: &Lens, model: Model) -> Result<Image> {
        Ok(self.render_with_stats(stack, lens, model)?.0)
    }

    pub fn render_with_stats(&self, stack: &LayerStack, lens: &Lens, model: Model) -> Result<(Image, RenderStats)> {
        let params = Params::new(stack, lens, model)?;
        let ctx = &self.ctx;
        let layers = params.layer_count as u64;
        let pixels = (params.width * params.height) as u64;
        let tiles = (params.tiles_x * params.tiles_y) as u64;

        let rgba: Vec<[f32; 4]> = stack.layers.iter().flat_map(|l| l.rgba.pixels.iter().copied()).collect();
        let disparity: Vec<f32> = stack.layers.iter().flat_map(|l| l.disparity.iter().copied()).collect();
        let rgba = Buffer::from_slice(ctx, "drbokeh rgba", &rgba)?;
        let disparity = Buffer::from_slice(ctx, "drbokeh disparity", &disparity)?;
        let area_lut = Buffer::from_slice(ctx, "drbokeh area_lut", &params.area_lut_f32())?;
        let kernel = Buffer::from_slice(ctx, "drbokeh kernel", &params.kernel_f32())?;
        let tile_bounds = Buffer::zeroed(ctx, "drbokeh tile_bounds", layers * tiles * VEC2)?;
        let tile_window = Buffer::zeroed(ctx, "drbokeh tile_window", layers * tiles * 4)?;
        let layer_cw = Buffer::zeroed(ctx, "drbokeh layer_cw", layers * pixels * VEC4)?;
        let layer_vis = Buffer::zeroed(ctx, "drbokeh layer_vis", layers * pixels * 4)?;
        let result = Buffer::zeroed(ctx, "drbokeh result", pixels * VEC4)?;

        let image_groups = self.layer.groups_for([params.width as u32, params.height as u32, 1]);
        let tile_groups = self.tile_bounds.groups_for([tiles as u32, 1, 1]);
        let mut batch = CommandBatch::new(ctx)?;
        for layer in 0..params.layer_count {
            let push = params.push(layer);
            batch.dispatch(&self.tile_bounds, &[rgba.all(), disparity.all(), tile_bounds.all()], &push, tile_groups)?;
            batch.dispatch(&self.tile_window, &[tile_bounds.all(), tile_window.all()], &push, tile_groups)?;
            batch.dispatch(
                &self.layer,
                &[rgba.all(), disparity.all(), tile_window.all(), area_lut.all(), kernel.all(), layer_cw.all(), layer_vis.all()],
                &push,
                image_groups,
            )?;
        }
        batch.dispatch(&self.composite, &[layer_cw.all(), layer_vis.all(), result.all()], &params.push(0), image_groups)?;
        batch.submit_and_wait()?;
        let stats = RenderStats { device_ns: batch.last_device_time_ns() };
        let pixels: Vec<[f32; 4]> = result.read(ctx)?;
        Ok((Image { width: params.width, height: params.height, pixels }, stats))
    }
}
