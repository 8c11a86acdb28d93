//! GPU host code of the gather baseline: uploads the image and its disparity, dispatches
//! `glsl/gather.comp` once, reads back.
use super::EDGE_WIDTH;
use crate::image::Image;
use crate::render::Lens;
use crate::shaders;
use crate::vk::{Buffer, CommandBatch, ComputePipeline, Context, Slot, TexelFormat};
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
}
const _: () = assert!(std::mem::size_of::<GatherPush>() == 48);

/// The gather baseline on the GPU.
pub struct Gather {
    ctx: Context,
    pipeline: ComputePipeline,
}

impl Gather {
    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::with_slots(ctx, &shaders::GATHER, &[Slot::Texels(TexelFormat::Vec4), Slot::Texels(TexelFormat::Float), Slot::Storage, Slot::Texels(TexelFormat::Float)], std::mem::size_of::<GatherPush>())?;
        Ok(Self { ctx: ctx.clone(), pipeline })
    }

    /// Renders `image` (linear, premultiplied) with per-pixel `disparity` through `lens`.
    pub fn run(&self, image: &Image, disparity: &[f32], lens: &Lens) -> Result<Image> {
        check_input(image, disparity)?;
        let (kernel_size, kernel) = lens.aperture.kernel_texels();
        let push = GatherPush {
            width: image.width as i32,
            height: image.height as i32,
            k: lens.coc.k_px,
            focus: lens.coc.focus_disparity,
            edge_width: EDGE_WIDTH,
            kernel_size: kernel_size as i32,
            pad: [0.0; 2],
            aperture: lens.aperture.gpu_params(),
        };
        dispatch_image_pass(&self.ctx, &self.pipeline, "gather", image, disparity, &kernel, &push)
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

/// One dispatch over the image of a pass reading (image, disparity, aperture kernel texels) and
/// writing an image: the shape both single-image baselines share.
pub(crate) fn dispatch_image_pass<P: bytemuck::Pod>(
    ctx: &Context,
    pipeline: &ComputePipeline,
    name: &str,
    image: &Image,
    disparity: &[f32],
    kernel: &[f32],
    push: &P,
) -> Result<Image> {
    let source = Buffer::from_slice(ctx, &format!("{name} image"), &image.pixels)?;
    let depth = Buffer::from_slice(ctx, &format!("{name} disparity"), disparity)?;
    let kernel = Buffer::from_slice(ctx, &format!("{name} kernel"), kernel)?;
    let result = Buffer::zeroed(ctx, &format!("{name} result"), std::mem::size_of_val(image.pixels.as_slice()) as u64)?;
    let groups = pipeline.groups_for([image.width as u32, image.height as u32, 1]);
    let mut batch = CommandBatch::new(ctx)?;
    batch.dispatch(pipeline, &[source.all(), depth.all(), result.all(), kernel.all()], push, groups)?;
    batch.submit_and_wait()?;
    let pixels: Vec<[f32; 4]> = result.read(ctx)?;
    Ok(Image { width: image.width, height: image.height, pixels })
}
