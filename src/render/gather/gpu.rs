//! GPU host code of the gather baseline: on frame tiles ([`crate::render::tiler`]), uploads
//! each tile's read rect of the image and its disparity, dispatches `glsl/gather.comp` over
//! its core, reads back.
use super::EDGE_WIDTH;
use crate::image::Image;
use crate::render::tiler::{
    crop_rows, rect_push, render_image_tiles, Footprint, FrameTiling, RenderOptions, RenderStats,
};
use crate::render::{Lens, SingleImageGpu};
use crate::shaders::{self, ShaderSource};
use crate::tile_grid::{MaxPyramid, Rect};
use crate::vk::{Buffer, ComputePipeline, Context, Slot, TexelFormat};
use crate::{Error, Result};

/// Push constants of `glsl/gather.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct GatherPush {
    width: i32,
    height: i32,
    k: f32,
    focus: f32,
    edge_width: f32,
    /// Side of the kernel image (0: none).
    kernel_size: i32,
    pad: [f32; 2],
    aperture: [f32; 4],
    /// The tile's core and read rects ([`rect_push`]).
    core: [i32; 4],
    read: [i32; 4],
}
const _: () = assert!(std::mem::size_of::<GatherPush>() == 80);

/// The gather baseline on the GPU.
pub struct Gather(ImageBaseline);

impl Gather {
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(Self(ImageBaseline::new::<GatherPush>(ctx, &shaders::GATHER, "gather")?))
    }
}

impl SingleImageGpu for Gather {
    fn run_with(&self, image: &Image, disparity: &[f32], lens: &Lens, options: &RenderOptions) -> Result<(Image, RenderStats)> {
        check_input(image, disparity)?;
        // A pixel's taps reach ceil(r + edge / 2) of its own radius, so a core's halo is its
        // largest radius's reach; + 1 covers the shader's f32 radius rounding the other way.
        let radius: Vec<f32> = disparity.iter().map(|&d| lens.coc.radius(d)).collect();
        let pyramid = MaxPyramid::new(image.width, image.height, &radius);
        let reach = |r: f32| (r + 0.5 * EDGE_WIDTH).ceil() as usize + 1;
        let whole = Rect { x0: 0, y0: 0, x1: image.width, y1: image.height };
        let push = |core, read, kernel_size| GatherPush {
            width: image.width as i32,
            height: image.height as i32,
            k: lens.coc.k_px,
            focus: lens.coc.focus_disparity,
            edge_width: EDGE_WIDTH,
            kernel_size,
            pad: [0.0; 2],
            aperture: lens.aperture.gpu_params(),
            core: rect_push(core),
            read: rect_push(read),
        };
        self.0.run(image, disparity, lens, options, reach(pyramid.max_in(whole)), |core| reach(pyramid.max_in(core)), push)
    }
}

/// A single-image baseline's one compute pipeline on a device ([`Gather`] and
/// [`crate::render::scatter::Scatter`], which check their input and work out their halos):
/// the aperture's kernel texels made, then its [`ImagePass`] on tiles.
pub(crate) struct ImageBaseline {
    ctx: Context,
    pipeline: ComputePipeline,
    name: &'static str,
}

impl ImageBaseline {
    /// The pipeline of `shader`, whose push constants are a `P`.
    pub fn new<P: bytemuck::Pod>(ctx: &Context, shader: &ShaderSource, name: &'static str) -> Result<Self> {
        let pipeline = ComputePipeline::with_slots(ctx, shader, &IMAGE_PASS_SLOTS, std::mem::size_of::<P>())?;
        Ok(Self { ctx: ctx.clone(), pipeline, name })
    }

    /// Renders on tiles whose halo is `halo(core)` (at most `max_halo`), each dispatched with
    /// `push(core, read, kernel side)` (the side 0: no kernel image).
    pub fn run<P: bytemuck::Pod>(
        &self,
        image: &Image,
        disparity: &[f32],
        lens: &Lens,
        options: &RenderOptions,
        max_halo: usize,
        halo: impl Fn(Rect) -> usize,
        push: impl Fn(Rect, Rect, i32) -> P,
    ) -> Result<(Image, RenderStats)> {
        let (kernel_size, kernel) = lens.aperture.kernel_texels();
        let pass = ImagePass { ctx: &self.ctx, pipeline: &self.pipeline, name: self.name, image, disparity, kernel: &kernel };
        pass.run(options, max_halo, halo, |core, read| push(core, read, kernel_size as i32))
    }
}

/// The checks the CPU reference leaves to its callers (it panics instead).
pub(crate) fn check_input(image: &Image, disparity: &[f32]) -> Result<()> {
    if image.pixels.is_empty() || disparity.len() != image.pixels.len() {
        return Err(Error::data(format!(
            "need one disparity per pixel of a non-empty image: {} values for {}x{}",
            disparity.len(),
            image.width,
            image.height
        )));
    }
    if disparity.iter().any(|d| !d.is_finite()) {
        return Err(Error::data("disparity must be finite"));
    }
    Ok(())
}

/// Bindings of an [`ImagePass`]: image, disparity (texels, read at lane-varying addresses),
/// result, kernel.
pub(crate) const IMAGE_PASS_SLOTS: [Slot; 4] = [
    Slot::Texels(TexelFormat::Vec4),
    Slot::Texels(TexelFormat::Float),
    Slot::Storage,
    Slot::Texels(TexelFormat::Float),
];

/// A tiled pass reading (image, disparity, aperture kernel texels) and writing an image: the
/// shape both single-image baselines share. Bindings: the read rect's RGBA and disparity, the
/// core's result, the kernel (shared by every tile).
pub(crate) struct ImagePass<'a> {
    pub ctx: &'a Context,
    pub pipeline: &'a ComputePipeline,
    pub name: &'a str,
    pub image: &'a Image,
    pub disparity: &'a [f32],
    pub kernel: &'a [f32],
}

impl ImagePass<'_> {
    /// Renders on tiles whose halo is `halo(core)` (at most `max_halo`), each dispatched with
    /// `push(core, read)`.
    pub fn run<P: bytemuck::Pod>(
        &self,
        options: &RenderOptions,
        max_halo: usize,
        halo: impl Fn(Rect) -> usize,
        push: impl Fn(Rect, Rect) -> P,
    ) -> Result<(Image, RenderStats)> {
        let (ctx, name, width) = (self.ctx, self.name, self.image.width);
        // Work bound: the square window of the largest halo per pixel.
        let frame = FrameTiling::new(width, self.image.height, 1, 1).with_work((2 * max_halo as u64 + 1).pow(2));
        let kernel = Buffer::from_slice(ctx, &format!("{name} kernel"), self.kernel)?;
        // RGBA + disparity per read pixel, RGBA per core pixel; the RGBA is the largest binding.
        let footprint = |tile| Footprint::per_pixel(&frame, tile, max_halo, 20, 16, 16);
        render_image_tiles(ctx, &frame, options, footprint, halo, |batch, core, read, room| {
            let (image, disparity) = (format!("{name} image"), format!("{name} disparity"));
            let rgba = crop_rows(&self.image.pixels, width, read);
            let source = Buffer::from_slices_with_room_in(ctx, batch, &image, read.area(), room.read, rgba)?;
            let disparity_rows = crop_rows(self.disparity, width, read);
            let depth =
                Buffer::from_slices_with_room_in(ctx, batch, &disparity, read.area(), room.read, disparity_rows)?;
            // The shader writes every core pixel.
            let (bytes, room) = (core.area() as u64 * 16, room.core as u64 * 16);
            let result = Buffer::uninitialised_with_room(ctx, &format!("{name} result"), bytes, room)?;
            let groups = self.pipeline.groups_for([core.width() as u32, core.height() as u32, 1]);
            batch.dispatch(
                self.pipeline,
                &[source.all(), depth.all(), result.all(), kernel.all()],
                &push(core, read),
                groups,
            )?;
            result.readable_in(batch)
        })
    }
}
