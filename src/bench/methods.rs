//! The method registry: a name, the input a method is entitled to, and a render closure.
use crate::camera::disparity_from_z;
use crate::image::Image;
use crate::raytrace::GroundTruth;
use crate::render::gather::{render_gather_cpu, Gather};
use crate::render::multiview::{Multiview, MultiviewParams};
use crate::render::oracle::render_oracle;
use crate::render::scatter::{render_scatter_cpu, Scatter};
use crate::render::vdslr::{Vdslr, VdslrParams};
use crate::render::Lens;
use crate::{Error, Result};

pub use crate::render::InputKind;

/// One scene as handed to a method.
pub struct BenchCase<'a> {
    pub truth: &'a GroundTruth,
    /// The ray tracer's camera in pixels, with a disk aperture (what the ray tracer traces).
    pub lens: &'a Lens,
    /// `1 / pinhole_depth` per pixel, 0 where nothing was hit.
    pub pinhole_disparity: &'a [f32],
}

impl<'a> BenchCase<'a> {
    /// Pinhole disparity as every single-image method reads it.
    pub fn disparity_of(truth: &GroundTruth) -> Vec<f32> {
        truth.pinhole_depth.iter().map(|&z| disparity_from_z(z)).collect()
    }

    /// The single-image input, checked for consistent sizes.
    pub fn single_image(&self) -> Result<(&'a Image, &'a [f32])> {
        let image = &self.truth.pinhole;
        if self.pinhole_disparity.len() != image.pixels.len() {
            return Err(Error::param(format!(
                "scene '{}': {} disparity values for a {}x{} pinhole image",
                self.truth.name,
                self.pinhole_disparity.len(),
                image.width,
                image.height
            )));
        }
        Ok((image, self.pinhole_disparity))
    }
}

pub type RenderFn = Box<dyn Fn(&BenchCase) -> Result<Image> + Send + Sync>;

pub struct Method {
    pub name: &'static str,
    pub input: InputKind,
    pub render: RenderFn,
}

impl Method {
    pub fn new(name: &'static str, input: InputKind, render: impl Fn(&BenchCase) -> Result<Image> + Send + Sync + 'static) -> Self {
        Self { name, input, render: Box::new(render) }
    }
}

/// The CPU references: the layered oracle and the two single-image baselines (`gather-cpu`,
/// `scatter-cpu`: the references of the Vulkan `gather` and `scatter`, cheap enough to keep).
pub fn cpu_methods() -> Vec<Method> {
    vec![
        Method::new("oracle", InputKind::Layers, |case| Ok(render_oracle(&case.truth.layers, &case.lens.coc))),
        Method::new("gather-cpu", InputKind::SingleImage, |case| {
            let (image, disparity) = case.single_image()?;
            Ok(render_gather_cpu(image, disparity, case.lens))
        }),
        Method::new("scatter-cpu", InputKind::SingleImage, |case| {
            let (image, disparity) = case.single_image()?;
            Ok(render_scatter_cpu(image, disparity, case.lens))
        }),
    ]
}

/// Keeps the methods named in `names` (in the registry's order); all of them for no names.
pub fn select_methods(methods: Vec<Method>, names: &[String]) -> Result<Vec<Method>> {
    if let Some(unknown) = names.iter().find(|n| !methods.iter().any(|m| m.name == n.as_str())) {
        let known: Vec<&str> = methods.iter().map(|m| m.name).collect();
        return Err(Error::param(format!("unknown method '{unknown}' (available: {})", known.join(", "))));
    }
    Ok(methods.into_iter().filter(|m| names.is_empty() || names.iter().any(|n| n == m.name)).collect())
}

/// Virtual DSLR as the benchmark runs it. Measured on `bench --quick` (mean PSNR): 64 -> 256
/// lens samples +1.2 dB (HDR bokeh balls stop being grainy; 1024 adds 0.2 dB more), 3 -> 10
/// search iterations +0.9 dB (the tilted wall's continuous depth needs them).
pub fn bench_vdslr_params() -> VdslrParams {
    VdslrParams { samples: 256, iterations: 10, ..VdslrParams::default() }
}

/// Multiview synthesis as the benchmark runs it. Measured on `bench --quick` (mean PSNR):
/// 64 samples 36.2 dB, 256 37.5, 512 37.7, 1024 37.8; cone tracing is worth +0.8 dB at 64
/// samples and nothing at 512, where it is kept (it never hurt).
pub fn bench_multiview_params() -> MultiviewParams {
    MultiviewParams { samples: 512, cone_scale: 1.0, ..MultiviewParams::default() }
}

/// The Vulkan renderers, on one device: the single-image baselines, Virtual DSLR (single
/// image), multiview synthesis and Dr.Bokeh (true layers; default model and released formulas).
pub fn gpu_methods(ctx: &crate::vk::Context) -> Result<Vec<Method>> {
    use crate::render::drbokeh::{DrBokehGpu, Model};
    let (gather, scatter) = (Gather::new(ctx)?, Scatter::new(ctx)?);
    let (vdslr, vdslr_params) = (Vdslr::new(ctx)?, bench_vdslr_params());
    let (multiview, multiview_params) = (Multiview::new(ctx)?, bench_multiview_params());
    let drbokeh = std::sync::Arc::new(DrBokehGpu::new(ctx)?);
    let compat = drbokeh.clone();
    Ok(vec![
        Method::new("gather", InputKind::SingleImage, move |case| {
            let (image, disparity) = case.single_image()?;
            gather.run(image, disparity, case.lens)
        }),
        Method::new("scatter", InputKind::SingleImage, move |case| {
            let (image, disparity) = case.single_image()?;
            scatter.run(image, disparity, case.lens)
        }),
        Method::new("vdslr", InputKind::SingleImage, move |case| {
            let (image, disparity) = case.single_image()?;
            vdslr.run(image, disparity, case.lens, &vdslr_params)
        }),
        Method::new("multiview", InputKind::Layers, move |case| multiview.run(&case.truth.layers, case.lens, &multiview_params)),
        Method::new("drbokeh", InputKind::Layers, move |case| drbokeh.render(&case.truth.layers, case.lens, Model::DrBokeh)),
        Method::new("drbokeh-compat", InputKind::Layers, move |case| compat.render(&case.truth.layers, case.lens, Model::Compat)),
    ])
}

/// Every method: the oracle, the Vulkan renderers on `ctx`, then the CPU baselines' references.
pub fn all_methods(ctx: &crate::vk::Context) -> Result<Vec<Method>> {
    let mut cpu = cpu_methods();
    let references = cpu.split_off(1);
    let mut methods = cpu;
    methods.extend(gpu_methods(ctx)?);
    methods.extend(references);
    Ok(methods)
}
