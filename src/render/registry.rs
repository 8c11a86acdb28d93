//! The method registry: the list of every rendering method, and nothing else. A new method is
//! its module, which declares its [`MethodSpec`] (say `foo::METHOD`: name, label, input,
//! settings, how to prepare its renderer and its backward pass if it has one) and turns
//! [`MethodSettings`] into its own parameters, plus one line `Method(&foo::METHOD)` in
//! [`Method::ALL`] (a named constant below is optional); `--method`, its flag checks and help,
//! `grad` and `fit-depth` (through the backward pass, [`MethodSpec::differentiable`]),
//! `lensblur methods` (whose `--json` the Blender add-on reads for its menu), the benchmark and
//! the tests' method loops follow. The README's method table is checked against it by a test.
//!
//! [`MethodSpec`]: crate::render::MethodSpec
//! [`MethodSettings`]: crate::render::MethodSettings
//! [`MethodSpec::differentiable`]: crate::render::MethodSpec::differentiable
use crate::render::method::Method;
use crate::render::{drbokeh, gather, gausspsf, multiview, oracle, scatter, vdslr};

// The CamelCase names keep the spelling of the enum these replaced (`Method::DrBokeh`), so code
// written against it still compiles.
#[allow(non_upper_case_globals)]
impl Method {
    pub const DrBokeh: Method = Method(&drbokeh::METHOD);
    pub const DrBokehCompat: Method = Method(&drbokeh::METHOD_COMPAT);
    pub const Multiview: Method = Method(&multiview::METHOD);
    pub const Vdslr: Method = Method(&vdslr::METHOD);
    pub const Oracle: Method = Method(&oracle::METHOD);
    pub const Gather: Method = Method(&gather::METHOD);
    pub const Scatter: Method = Method(&scatter::METHOD);
    pub const GaussPsf: Method = Method(&gausspsf::METHOD);

    /// Every method, in the order `--help`, `lensblur methods` and the add-on list them (the
    /// default first: the add-on's menu starts on it).
    pub const ALL: &'static [Method] = &[
        Method::DrBokeh,
        Method::DrBokehCompat,
        Method::Multiview,
        Method::Vdslr,
        Method::Oracle,
        Method::Gather,
        Method::Scatter,
        Method::GaussPsf,
    ];
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::image::Image;
    use crate::render::tiler::RenderOptions;
    use crate::render::{InputKind, Lens, MethodInput, MethodSettings};
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
        let settings = MethodSettings { samples: 16, ..MethodSettings::default() };
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
        // First: the Blender add-on's menu (a dynamic enum) starts on its first item.
        assert_eq!(Method::ALL[0], Method::default());
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
