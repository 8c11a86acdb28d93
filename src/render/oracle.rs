//! The layered oracle: the best a layered method can do when every layer is a fronto-parallel
//! plane. Each TRUE layer is blurred with the exact image of the aperture (disk, polygon or
//! kernel image; mirrored for layers nearer than focus) at its own constant CoC, and the
//! results are composited back to front with premultiplied "over". It needs the hidden content
//! that only a ray tracer (or a render-layer pipeline) has, so it bounds what Dr.Bokeh-style
//! methods can reach and is the reference the benchmark ranks the others against.
use crate::image::Image;
use crate::render::disk::{disk_blur_cpu, DiskKernel};
use crate::render::method::{InputKind, MethodInput, MethodSettings, MethodSpec};
use crate::render::tiler::RenderOptions;
use crate::render::Lens;
use crate::stack::{Layer, LayerStack};

/// The oracle in the registry: CPU only.
pub const METHOD: MethodSpec = MethodSpec {
    name: "oracle",
    label: "Per-layer blur",
    summary: "Blur each layer and composite it over (CPU)",
    input: InputKind::Layers,
    uses_gpu: false,
    settings: &[],
    prepare: |_| Ok(Box::new(|input: MethodInput<'_>, lens: &Lens, _: &RenderOptions, _: &MethodSettings| Ok(render_oracle(input.layers()?, lens)))),
    differentiable: None,
    fast_on_cpu: crate::render::method::never_fast_on_cpu,
};

/// Renders `stack` (front to back, premultiplied) through `lens`, one aperture image per layer.
pub fn render_oracle(stack: &LayerStack, lens: &Lens) -> Image {
    let mut out = Image::new(stack.width, stack.height);
    for layer in stack.layers.iter().rev() {
        let Some(disparity) = mean_disparity(layer) else {
            continue; // a fully transparent layer contributes nothing
        };
        let kernel = DiskKernel::shaped(lens.coc.radius(disparity), &lens.aperture, lens.coc.relative_disparity(disparity));
        let blurred = disk_blur_cpu(&layer.rgba, &kernel);
        composite_over(&blurred, &mut out);
    }
    out
}

/// Alpha-weighted mean disparity: the plane a billboard layer lies on (its disparity is
/// constant where it is opaque; transparent pixels must not pull the mean).
fn mean_disparity(layer: &Layer) -> Option<f32> {
    let (mut sum, mut weight) = (0.0f64, 0.0f64);
    for (p, &d) in layer.rgba.pixels.iter().zip(&layer.disparity) {
        sum += p[3] as f64 * d as f64;
        weight += p[3] as f64;
    }
    (weight > 0.0).then(|| (sum / weight) as f32)
}

/// `back = front + (1 - alpha_front) * back`, premultiplied.
fn composite_over(front: &Image, back: &mut Image) {
    for (b, f) in back.pixels.iter_mut().zip(&front.pixels) {
        let keep = 1.0 - f[3];
        for c in 0..4 {
            b[c] = f[c] + keep * b[c];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};

    fn layer(name: &str, rgba: Image, disparity: f32) -> Layer {
        let n = rgba.pixels.len();
        Layer { name: name.into(), rgba, disparity: vec![disparity; n] }
    }

    fn checker(w: usize, h: usize) -> Image {
        Image::from_fn(w, h, |x, y| if (x / 3 + y / 3) % 2 == 0 { [0.9, 0.2, 0.1, 1.0] } else { [0.1, 0.3, 0.8, 1.0] })
    }

    #[test]
    fn single_opaque_layer_equals_its_disk_blur() {
        let coc = CocModel::new(20.0, 0.5).unwrap();
        let img = checker(31, 23);
        let stack = LayerStack::new(31, 23, vec![layer("bg", img.clone(), 0.2)]).unwrap();
        // Over black with alpha 1 everywhere is the identity: the same floats, bit for bit.
        assert_eq!(render_oracle(&stack, &Lens { coc, aperture: Aperture::Disk }), disk_blur_cpu(&img, &DiskKernel::new(coc.radius(0.2))));
    }

    #[test]
    fn transparent_front_layer_leaves_the_back_blur() {
        let coc = CocModel::new(20.0, 0.5).unwrap();
        let back = checker(31, 23);
        let front = Image::filled(31, 23, [0.0; 4]);
        let stack = LayerStack::new(31, 23, vec![layer("fg", front, 0.9), layer("bg", back.clone(), 0.2)]).unwrap();
        assert_eq!(render_oracle(&stack, &Lens { coc, aperture: Aperture::Disk }), disk_blur_cpu(&back, &DiskKernel::new(coc.radius(0.2))));
    }

    #[test]
    fn blurred_opaque_front_square_lets_the_background_through_at_its_rim() {
        // A sharp-edged opaque front square blurred by 4 px: half coverage on its edge, so the
        // background shows through at half strength there (true partial occlusion).
        let coc = CocModel::new(10.0, 0.0).unwrap();
        let front = Image::from_fn(41, 41, |x, y| if (10..31).contains(&x) && (10..31).contains(&y) { [1.0, 0.0, 0.0, 1.0] } else { [0.0; 4] });
        let back = Image::filled(41, 41, [0.0, 0.0, 1.0, 1.0]);
        let stack = LayerStack::new(41, 41, vec![layer("fg", front, 0.4), layer("bg", back, 0.0)]).unwrap();
        let out = render_oracle(&stack, &Lens { coc, aperture: Aperture::Disk });
        let centre = out.get(20, 20);
        assert!((centre[0] - 1.0).abs() < 1e-5 && centre[2].abs() < 1e-5, "{centre:?}");
        // Pixel 9 lies 0.5 px outside the edge: it sees the part of its r = 4 disk beyond a
        // chord 0.5 from the centre, (16 acos(1/8) - 0.5 sqrt(15.75)) / (16 pi) = 0.4206.
        // Tolerance 0.02: the kernel integrates pixel coverage on an 8x8 sub-grid.
        let rim = out.get(9, 20);
        assert!((rim[0] + rim[2] - 1.0).abs() < 1e-5, "opaque result: shares add to one");
        assert!((rim[0] - 0.4206).abs() < 0.02, "{rim:?}");
    }
}
