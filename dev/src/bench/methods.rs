//! The benchmark's methods: the registry's ([`Method::ALL`]) on the inputs each is entitled
//! to, plus a few bench-only variants.
use lensblur::camera::disparity_from_z;
use lensblur::image::Image;
use lensblur::raytrace::GroundTruth;
use lensblur::render::drbokeh::RenderOptions;
use lensblur::render::{Lens, Method, MethodInput, MethodSettings};
use lensblur::stack::deep::{deep_to_layers, DeepImage, DeepLayerOptions};
use lensblur::input::auto_layers;
use lensblur::stack::AutoLayerOptions;
use lensblur::vk::Context;
use lensblur::{Error, Result};

pub use lensblur::render::InputKind;

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
            return Err(Error::data(format!(
                "scene '{}': {} disparity values for a {}x{} pinhole image",
                self.truth.name,
                self.pinhole_disparity.len(),
                image.width,
                image.height
            )));
        }
        Ok((image, self.pinhole_disparity))
    }

    /// The input of `kind`: the true layers, or the pinhole image and its disparity.
    pub fn input(&self, kind: InputKind) -> Result<MethodInput<'a>> {
        Ok(match kind {
            InputKind::Layers => MethodInput::Layers(&self.truth.layers),
            InputKind::SingleImage => {
                let (image, disparity) = self.single_image()?;
                MethodInput::SingleImage { image, disparity }
            }
        })
    }
}

pub type RenderFn = Box<dyn Fn(&BenchCase) -> Result<Image> + Send + Sync>;

/// One column of the benchmark: a registry method on its entitled input, or a bench-only
/// variant of one (a CPU reference, the single-image path of a layered method).
pub struct BenchMethod {
    pub name: &'static str,
    pub input: InputKind,
    pub render: RenderFn,
}

impl BenchMethod {
    pub fn new(name: &'static str, input: InputKind, render: impl Fn(&BenchCase) -> Result<Image> + Send + Sync + 'static) -> Self {
        Self { name, input, render: Box::new(render) }
    }

    /// `method` as the registry declares it, prepared once on `ctx`, run with its tuned settings.
    pub fn on_device(method: Method, ctx: &Context) -> Result<Self> {
        let renderer = method.prepare(Some(ctx))?;
        Ok(Self::new(method.name(), method.input(), move |case| {
            renderer.render(case.input(method.input())?, case.lens, &RenderOptions::default(), &MethodSettings::default())
        }))
    }

    /// `method` on the CPU (its reference path where it has a Vulkan one), named `name`.
    /// Preparing a CPU path builds nothing, so it happens per render, where errors are reported.
    pub fn on_cpu(method: Method, name: &'static str) -> Self {
        Self::new(name, method.input(), move |case| {
            let renderer = method.prepare(None)?;
            renderer.render(case.input(method.input())?, case.lens, &RenderOptions::default(), &MethodSettings::default())
        })
    }
}

/// The GPU baselines whose CPU references the benchmark also scores (cheap enough to keep).
const CPU_REFERENCES: [(Method, &str); 2] = [(Method::Gather, "gather-cpu"), (Method::Scatter, "scatter-cpu")];

/// The CPU methods: those of the registry that need no device (the layered oracle, GaussPSF),
/// then the references of the single-image baselines (`gather-cpu`, `scatter-cpu`).
pub fn cpu_methods() -> Vec<BenchMethod> {
    let registry = Method::ALL.iter().filter(|m| !m.uses_gpu()).map(|m| BenchMethod::on_cpu(*m, m.name()));
    registry.chain(CPU_REFERENCES.iter().map(|(m, name)| BenchMethod::on_cpu(*m, name))).collect()
}

/// Keeps the methods named in `names` (in the registry's order); all of them for no names.
pub fn select_methods(methods: Vec<BenchMethod>, names: &[String]) -> Result<Vec<BenchMethod>> {
    if let Some(unknown) = names.iter().find(|n| !methods.iter().any(|m| m.name == n.as_str())) {
        let known: Vec<&str> = methods.iter().map(|m| m.name).collect();
        return Err(Error::invalid("method", format!("unknown method '{unknown}' (available: {})", known.join(", "))));
    }
    Ok(methods.into_iter().filter(|m| names.is_empty() || names.iter().any(|n| n == m.name)).collect())
}

/// The Vulkan renderers of the registry on one device, then `drbokeh-auto`: what `lensblur
/// render` does with one image + depth (split it into layers with solved mattes and push-pull
/// fill of the hidden background, then Dr.Bokeh), `drbokeh-auto-sampled`: the same with the
/// layering before issue 46, and `drbokeh-deep`: what it does with a deep file
/// of the true layers (one sample per covered pixel per layer, clustered back into layers).
pub fn gpu_methods(ctx: &Context) -> Result<Vec<BenchMethod>> {
    let mut methods: Vec<BenchMethod> =
        Method::ALL.iter().filter(|m| m.uses_gpu()).map(|m| BenchMethod::on_device(*m, ctx)).collect::<Result<_>>()?;
    let drbokeh = Method::DrBokeh.prepare(Some(ctx))?;
    methods.push(BenchMethod::new("drbokeh-auto", InputKind::SingleImage, move |case| {
        let (image, disparity) = case.single_image()?;
        let (stack, _, margin) = auto_layers(image, disparity, &case.lens.coc, &AutoLayerOptions::default());
        let canvas = drbokeh.render(MethodInput::Layers(&stack), case.lens, &RenderOptions::default(), &MethodSettings::default())?;
        Ok(canvas.without_border(margin).expect("the canvas holds the frame"))
    }));
    // The layering before issue 46, for before/after tables in one run.
    let drbokeh = Method::DrBokeh.prepare(Some(ctx))?;
    methods.push(BenchMethod::new("drbokeh-auto-sampled", InputKind::SingleImage, move |case| {
        let (image, disparity) = case.single_image()?;
        let (stack, _, _) = auto_layers(image, disparity, &case.lens.coc, &AutoLayerOptions::sampled());
        drbokeh.render(MethodInput::Layers(&stack), case.lens, &RenderOptions::default(), &MethodSettings::default())
    }));
    let drbokeh = Method::DrBokeh.prepare(Some(ctx))?;
    methods.push(BenchMethod::new("drbokeh-deep", InputKind::Layers, move |case| {
        let deep = DeepImage::from_stack(&case.truth.layers);
        let stack = deep_to_layers(&deep, &case.lens.coc, &DeepLayerOptions::default())?;
        drbokeh.render(MethodInput::Layers(&stack), case.lens, &RenderOptions::default(), &MethodSettings::default())
    }));
    Ok(methods)
}

/// Every method: the CPU ones of the registry, the Vulkan renderers on `ctx`, then the CPU
/// baselines' references. Without a device, only the CPU methods.
pub fn all_methods(ctx: Option<&Context>) -> Result<Vec<BenchMethod>> {
    let mut cpu = cpu_methods();
    let Some(ctx) = ctx else { return Ok(cpu) };
    let references = cpu.split_off(cpu.len() - CPU_REFERENCES.len());
    let mut methods = cpu;
    methods.extend(gpu_methods(ctx)?);
    methods.extend(references);
    Ok(methods)
}
