//! The method registry: every rendering method, declared once. A new method is its module
//! (exporting a [`MethodSpec`], say `foo::METHOD`) plus one line `Method(&foo::METHOD)` in
//! [`Method::ALL`] (a named constant below is optional); `--method`, its flag checks and help,
//! `grad` and `fit-depth` (through its backward pass, [`MethodSpec::differentiable`]),
//! `lensblur methods`, the benchmark and the tests' method loops follow. The Blender add-on's
//! list and the README's method table are checked against it by tests.
use crate::image::Image;
use crate::render::drbokeh::{render_cpu, BackwardOptions, DrBokehGpu, DrBokehGpuGrad, Model};
use crate::render::grad::{Differentiable, Slope};
use crate::render::gather::{render_gather_cpu, Gather};
use crate::render::method::{InputKind, Method, MethodInput, MethodSpec, Renderer, Setting};
use crate::render::multiview::{render_multiview_cpu, Multiview};
use crate::render::oracle::render_oracle;
use crate::render::scatter::{render_scatter_cpu, Scatter};
use crate::render::tiler::{RenderOptions, RenderStats};
use crate::render::vdslr::{render_vdslr_cpu, Vdslr};
use crate::render::{Lens, MethodSettings};
use crate::vk::Context;
use crate::Result;

// The CamelCase names keep the spelling of the enum these replaced (`Method::DrBokeh`), so code
// written against it still compiles.
#[allow(non_upper_case_globals)]
impl Method {
    pub const DrBokeh: Method = Method(&DRBOKEH);
    pub const DrBokehCompat: Method = Method(&DRBOKEH_COMPAT);
    pub const Multiview: Method = Method(&MULTIVIEW);
    pub const Vdslr: Method = Method(&VDSLR);
    pub const Oracle: Method = Method(&ORACLE);
    pub const Gather: Method = Method(&GATHER);
    pub const Scatter: Method = Method(&SCATTER);

    /// Every method, in the order `--help`, `lensblur methods` and the add-on list them.
    pub const ALL: &'static [Method] = &[
        Method::DrBokeh,
        Method::DrBokehCompat,
        Method::Multiview,
        Method::Vdslr,
        Method::Oracle,
        Method::Gather,
        Method::Scatter,
    ];
}

const DRBOKEH: MethodSpec = MethodSpec {
    name: "drbokeh",
    label: "Dr.Bokeh",
    summary: "Layered occlusion-aware gather (Vulkan); the default",
    input: InputKind::Layers,
    uses_gpu: true,
    settings: &[],
    prepare: |ctx| drbokeh(ctx, Model::DrBokeh),
    differentiable: Some(|ctx, slope| drbokeh_backward(ctx, Model::DrBokeh, slope)),
};

const DRBOKEH_COMPAT: MethodSpec = MethodSpec {
    name: "drbokeh-compat",
    label: "Dr.Bokeh (released code)",
    summary: "Dr.Bokeh with the formulas of its released code (Vulkan)",
    input: InputKind::Layers,
    uses_gpu: true,
    settings: &[],
    prepare: |ctx| drbokeh(ctx, Model::Compat),
    differentiable: Some(|ctx, slope| drbokeh_backward(ctx, Model::Compat, slope)),
};

const MULTIVIEW: MethodSpec = MethodSpec {
    name: "multiview",
    label: "Multiview",
    summary: "Lens rays through the layers (Lee et al. 2009, Vulkan)",
    input: InputKind::Layers,
    uses_gpu: true,
    settings: &[Setting::Samples],
    prepare: multiview,
    differentiable: None,
};

const VDSLR: MethodSpec = MethodSpec {
    name: "vdslr",
    label: "Virtual DSLR",
    summary: "Pseudo ray tracing of the flattened image + depth (Yang et al. 2016, Vulkan)",
    input: InputKind::SingleImage,
    uses_gpu: true,
    settings: &Setting::ALL,
    prepare: vdslr,
    differentiable: None,
};

const ORACLE: MethodSpec = MethodSpec {
    name: "oracle",
    label: "Per-layer blur",
    summary: "Blur each layer and composite it over (CPU)",
    input: InputKind::Layers,
    uses_gpu: false,
    settings: &[],
    prepare: |_| Ok(Box::new(|input: MethodInput<'_>, lens: &Lens, _: &RenderOptions, _: &MethodSettings| Ok(render_oracle(input.layers()?, lens)))),
    differentiable: None,
};

const GATHER: MethodSpec = MethodSpec {
    name: "gather",
    label: "Gather",
    summary: "Single-image gather baseline, like the Defocus node (Vulkan)",
    input: InputKind::SingleImage,
    uses_gpu: true,
    settings: &[],
    prepare: |ctx| Ok(baseline(ctx.map(Gather::new).transpose()?, Gather::run_with, render_gather_cpu)),
    differentiable: None,
};

const SCATTER: MethodSpec = MethodSpec {
    name: "scatter",
    label: "Scatter",
    summary: "Single-image scatter baseline (BokehMe's classical renderer, Vulkan)",
    input: InputKind::SingleImage,
    uses_gpu: true,
    settings: &[],
    prepare: |ctx| Ok(baseline(ctx.map(Scatter::new).transpose()?, Scatter::run_with, render_scatter_cpu)),
    differentiable: None,
};

fn drbokeh(ctx: Option<&Context>, model: Model) -> Result<Box<dyn Renderer>> {
    let gpu = ctx.map(DrBokehGpu::new).transpose()?;
    Ok(Box::new(move |input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, _: &MethodSettings| {
        let stack = input.layers()?;
        match &gpu {
            Some(gpu) => Ok(gpu.render_with(stack, lens, model, options)?.0),
            None => render_cpu(stack, lens, model),
        }
    }))
}

fn drbokeh_backward(ctx: &Context, model: Model, slope: Slope) -> Result<Box<dyn Differentiable>> {
    let options = match slope {
        Slope::Exact => BackwardOptions::exact(),
        Slope::Leaky => BackwardOptions::leaky(),
    };
    Ok(Box::new(DrBokehGpuGrad::new(ctx, model, options)?))
}

fn multiview(ctx: Option<&Context>) -> Result<Box<dyn Renderer>> {
    let gpu = ctx.map(Multiview::new).transpose()?;
    Ok(Box::new(move |input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, settings: &MethodSettings| {
        let stack = input.layers()?;
        match &gpu {
            Some(gpu) => Ok(gpu.run_with(stack, lens, &settings.multiview, options)?.0),
            None => render_multiview_cpu(stack, lens, &settings.multiview),
        }
    }))
}

fn vdslr(ctx: Option<&Context>) -> Result<Box<dyn Renderer>> {
    let gpu = ctx.map(Vdslr::new).transpose()?;
    Ok(Box::new(move |input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, settings: &MethodSettings| {
        let (image, disparity) = input.single_image()?;
        match &gpu {
            Some(gpu) => Ok(gpu.run_with(image, disparity, lens, &settings.vdslr, options)?.0),
            None => render_vdslr_cpu(image, disparity, lens, &settings.vdslr),
        }
    }))
}

/// The single-image baselines: one tiled GPU pass, or its CPU reference.
fn baseline<G: Send + Sync + 'static>(
    gpu: Option<G>,
    run: fn(&G, &Image, &[f32], &Lens, &RenderOptions) -> Result<(Image, RenderStats)>,
    cpu: fn(&Image, &[f32], &Lens) -> Image,
) -> Box<dyn Renderer> {
    Box::new(move |input: MethodInput<'_>, lens: &Lens, options: &RenderOptions, _: &MethodSettings| {
        let (image, disparity) = input.single_image()?;
        match &gpu {
            Some(gpu) => Ok(run(gpu, image, disparity, lens, options)?.0),
            None => Ok(cpu(image, disparity, lens)),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::stack::{Layer, LayerStack};

    const COLOUR: [f32; 4] = [0.25, 0.5, 0.75, 1.0];

    /// Two layers of one colour: a near square (alpha 1 inside, 0 outside) over an opaque far
    /// layer, out of focus on both sides of the focal plane.
    fn one_colour_stack(n: usize) -> LayerStack {
        let square = |x: usize, y: usize| (4..n - 4).contains(&x) && (4..n - 4).contains(&y);
        let near = Image::from_fn(n, n, |x, y| if square(x, y) { COLOUR } else { [0.0; 4] });
        let layers = vec![
            Layer { name: "near".into(), rgba: near, disparity: vec![0.9; n * n] },
            Layer { name: "far".into(), rgba: Image::from_fn(n, n, |_, _| COLOUR), disparity: vec![0.1; n * n] },
        ];
        LayerStack::new(n, n, layers).unwrap()
    }

    /// Each method normalises its weights: a frame of one colour keeps it under any blur. The
    /// CoC is 1.6 px; a 4 px border is left out, where each method extends the frame its own way.
    /// Tolerance 1e-3: f32 sums of a few hundred normalised weights.
    #[test]
    fn every_registered_method_renders_and_keeps_one_colour() {
        let n = 16;
        let lens = Lens { coc: CocModel { k_px: 4.0, focus_disparity: 0.5 }, aperture: Aperture::Disk };
        let mut settings = MethodSettings::default();
        (settings.vdslr.samples, settings.multiview.samples) = (16, 16);
        let stack = one_colour_stack(n);
        for method in Method::ALL {
            let image = method
                .render_with(None, &stack, &lens, &RenderOptions::default(), &settings)
                .unwrap_or_else(|e| panic!("{method}: {e}"));
            assert_eq!((image.width, image.height), (n, n), "{method}");
            for (x, y) in (4..n - 4).flat_map(|y| (4..n - 4).map(move |x| (x, y))) {
                let got = image.get(x, y);
                let off = (0..4).map(|c| (got[c] - COLOUR[c]).abs()).fold(0.0, f32::max);
                assert!(off < 1e-3, "{method} at ({x}, {y}): {got:?}");
            }
        }
    }

    #[test]
    fn names_are_unique_and_parse_back() {
        for method in Method::ALL {
            assert_eq!(method.name().parse::<Method>().unwrap(), *method);
            assert_eq!(Method::ALL.iter().filter(|m| m.name() == method.name()).count(), 1, "{method}");
        }
        assert!(Method::ALL.contains(&Method::default()));
        let error = "nope".parse::<Method>().unwrap_err().to_string();
        assert!(error.contains("unknown method 'nope' (available: drbokeh, drbokeh-compat"), "{error}");
    }

    /// A renderer handed the other kind of input says so instead of rendering something else.
    #[test]
    fn a_renderer_refuses_the_input_its_method_does_not_read() {
        let stack = one_colour_stack(12);
        let (image, disparity) = stack.flatten();
        let lens = Lens { coc: CocModel { k_px: 2.0, focus_disparity: 0.5 }, aperture: Aperture::Disk };
        let (options, settings) = (RenderOptions::default(), MethodSettings::default());
        for method in Method::ALL {
            let renderer = method.prepare(None).unwrap();
            let wrong = match method.input() {
                InputKind::Layers => MethodInput::SingleImage { image: &image, disparity: &disparity },
                InputKind::SingleImage => MethodInput::Layers(&stack),
            };
            let error = renderer.render(wrong, &lens, &options, &settings).err().map(|e| e.to_string());
            assert!(error.is_some_and(|e| e.contains("was handed")), "{method}");
        }
    }
}
