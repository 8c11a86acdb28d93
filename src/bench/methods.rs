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
use crate::stack::{split_into_layers, AutoLayerOptions};
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
        Method::new("oracle", InputKind::Layers, |case| Ok(render_oracle(&case.truth.layers, case.lens))),
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

/// The Vulkan renderers, on one device: the single-image baselines, Virtual DSLR (single
/// image), multiview synthesis and Dr.Bokeh (true layers; default model and released formulas).
pub fn gpu_methods(ctx: &crate::vk::Context) -> Result<Vec<Method>> {
    use crate::render::drbokeh::{DrBokehGpu, Model};
    let (gather, scatter) = (Gather::new(ctx)?, Scatter::new(ctx)?);
    let (vdslr, vdslr_params) = (Vdslr::new(ctx)?, VdslrParams::tuned());
    let (multiview, multiview_params) = (Multiview::new(ctx)?, MultiviewParams::tuned());
    let drbokeh = std::sync::Arc::new(DrBokehGpu::new(ctx)?);
    let (compat, auto) = (drbokeh.clone(), drbokeh.clone());
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
        // What `lensblur render` does with one image + depth: split it into layers (soft cuts,
        // push-pull fill of the hidden background), then Dr.Bokeh.
        Method::new("drbokeh-auto", InputKind::SingleImage, move |case| {
            let (image, disparity) = case.single_image()?;
            let stack = split_into_layers(image, disparity, &case.lens.coc, &AutoLayerOptions::default());
            auto.render(&stack, case.lens, Model::DrBokeh)
        }),
    ])
}

/// Every method: the oracle, the Vulkan renderers on `ctx`, then the CPU baselines' references.
/// Without a device, only the CPU references.
pub fn all_methods(ctx: Option<&crate::vk::Context>) -> Result<Vec<Method>> {
    let mut cpu = cpu_methods();
    let Some(ctx) = ctx else { return Ok(cpu) };
    let references = cpu.split_off(1);
    let mut methods = cpu;
    methods.extend(gpu_methods(ctx)?);
    methods.extend(references);
    Ok(methods)
}
