//! Stacks handed over as flat arrays (the Python package's numpy arrays), read with the same
//! checks and depth fill as a file's layers, so an array and an EXR of the same pixels render
//! alike and their gradients map back the same way.
use std::path::Path;

use super::depth_clean::{check_finite, depth_to_disparity};
use super::{DepthKind, Layer, LayerStack};
use crate::image::Image;
use crate::stack::gradients::{stored_depth_gradient, StackGradients};
use crate::{Error, Result};

/// A stack read from arrays, with what mapping its gradients back needs.
#[derive(Clone, Debug)]
pub struct ArrayStack {
    pub stack: LayerStack,
    /// The arrays held one image (H, W, 4) rather than layers (L, H, W, 4).
    pub single_image: bool,
    pub depth_kind: DepthKind,
    /// Per layer: the depth fill's weight of every pixel (0 where the depth was filled).
    pub depth_weights: Vec<Vec<f32>>,
}

fn shape_text(shape: &[usize]) -> String {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    format!("({})", dims.join(", "))
}

/// Reads premultiplied RGBA `rgba` of shape (L, H, W, 4), or one image (H, W, 4), and depth of
/// the matching shape (L, H, W) or (H, W) stored as `kind`, both row-major. Colour and alpha
/// must be finite; depth is checked and filled under transparent pixels as a file's is.
pub fn stack_from_arrays(
    rgba: &[f32],
    rgba_shape: &[usize],
    depth: &[f32],
    depth_shape: &[usize],
    kind: DepthKind,
) -> Result<ArrayStack> {
    let (layers, height, width, single_image) = match *rgba_shape {
        [l, h, w, 4] => (l, h, w, false),
        [h, w, 4] => (1, h, w, true),
        _ => {
            return Err(Error::data(format!(
                "layers must be premultiplied RGBA of shape (L, H, W, 4), or one image (H, W, 4); got shape {}",
                shape_text(rgba_shape)
            )))
        }
    };
    let pixel_shape = &rgba_shape[..rgba_shape.len() - 1];
    if depth_shape != pixel_shape {
        return Err(Error::data(format!(
            "depth must have shape {} to match layers of shape {}; got shape {}",
            shape_text(pixel_shape),
            shape_text(rgba_shape),
            shape_text(depth_shape)
        )));
    }
    if layers == 0 || height == 0 || width == 0 {
        return Err(Error::data(format!("layers of shape {} hold no pixels", shape_text(rgba_shape))));
    }
    let n = width * height;
    if rgba.len() != layers * n * 4 || depth.len() != layers * n {
        return Err(Error::internal(format!(
            "{} colour and {} depth values for shape {}",
            rgba.len(),
            depth.len(),
            shape_text(rgba_shape)
        )));
    }
    let mut stack_layers = Vec::with_capacity(layers);
    let mut depth_weights = Vec::with_capacity(layers);
    for l in 0..layers {
        let name = if single_image { "image".to_string() } else { format!("layer {l}") };
        let pixels: Vec<[f32; 4]> = bytemuck::cast_slice(&rgba[l * n * 4..(l + 1) * n * 4]).to_vec();
        // One pass on the happy path; the file reader's check words the error.
        if pixels.iter().flatten().any(|v| !v.is_finite()) {
            for (c, channel) in ["R", "G", "B", "A"].into_iter().enumerate() {
                let mut values: Vec<f32> = pixels.iter().map(|p| p[c]).collect();
                check_finite(Path::new("layers"), &name, channel, &mut values, false)?;
            }
        }
        let alpha: Vec<f32> = pixels.iter().map(|p| p[3]).collect();
        let layer_depth = &depth[l * n..(l + 1) * n];
        let (disparity, _, weights) =
            depth_to_disparity(Path::new("depth"), (&name, "depth"), (width, height), layer_depth, &alpha, kind)?;
        stack_layers.push(Layer { name, rgba: Image { width, height, pixels }, disparity });
        depth_weights.push(weights);
    }
    Ok(ArrayStack {
        stack: LayerStack::new(width, height, stack_layers)?,
        single_image,
        depth_kind: kind,
        depth_weights,
    })
}

/// The inverse of [`stack_from_arrays`]: `stack`'s premultiplied RGBA as (L, H, W, 4) and its
/// depth as (L, H, W) stored as `kind` (filled under transparent pixels, as rendered).
pub fn stack_to_arrays(stack: LayerStack, kind: DepthKind) -> (Vec<f32>, Vec<f32>) {
    let n = stack.width * stack.height;
    let mut rgba = Vec::with_capacity(stack.layers.len() * n * 4);
    let mut depth = Vec::with_capacity(stack.layers.len() * n);
    for layer in stack.layers {
        depth.extend(layer.disparity.iter().map(|&d| kind.from_disparity(d)));
        rgba.extend_from_slice(bytemuck::cast_slice(&layer.rgba.pixels));
    }
    (rgba, depth)
}

/// Why a single image's gradients do not map back: a layered method renders it split into
/// layers, and those layers are not its pixels.
pub const AUTO_LAYERED_GRADIENTS: &str = "gradients of an auto-layered image do not map onto its channels";

impl ArrayStack {
    /// dL/d(the arrays as handed over) from `grads` of a render of this stack: premultiplied
    /// RGBA as (L, H, W, 4) and depth as (L, H, W) in the arrays' depth convention, through the
    /// fill (a filled pixel passes its gradient on to the covered ones it came from).
    pub fn gradients(&self, grads: &StackGradients) -> Result<(Vec<f32>, Vec<f32>)> {
        if grads.layers.len() != self.stack.layers.len() {
            return Err(Error::internal(format!(
                "{} layer gradients for {} layers",
                grads.layers.len(),
                self.stack.layers.len()
            )));
        }
        let mut rgba = Vec::new();
        let mut depth = Vec::new();
        for ((layer, grad), weights) in self.stack.layers.iter().zip(&grads.layers).zip(&self.depth_weights) {
            rgba.extend_from_slice(bytemuck::cast_slice(&grad.rgba));
            depth.extend(stored_depth_gradient(self.depth_kind, layer, weights, &grad.disparity)?);
        }
        Ok((rgba, depth))
    }
}

/// dL/d(render) handed over as (H, W, 3) RGB or (H, W, 4) RGBA for a `width` x `height`
/// render. The render's alpha is not differentiated, so an alpha gradient must be 0 (a loss
/// that reads alpha would get a wrong gradient, not an error, were it dropped).
pub fn grad_output_from_array(values: &[f32], shape: &[usize], width: usize, height: usize) -> Result<Image> {
    let channels = match *shape {
        [h, w, c @ (3 | 4)] if (h, w) == (height, width) => c,
        _ => {
            return Err(Error::data(format!(
            "grad_output (dL/d(render)) must have shape ({height}, {width}, 3) or ({height}, {width}, 4); got shape {}",
            shape_text(shape)
        )))
        }
    };
    let bad = values.iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        return Err(Error::data(format!("grad_output (dL/d(render)) has {bad} NaN/Inf value(s)")));
    }
    let pixels: Vec<[f32; 4]> =
        values.chunks_exact(channels).map(|p| [p[0], p[1], p[2], if channels == 4 { p[3] } else { 0.0 }]).collect();
    if pixels.iter().any(|p| p[3] != 0.0) {
        return Err(Error::data(
            "grad_output (dL/d(render)) has a non-zero alpha gradient, but the render's alpha is not differentiated: \
             leave alpha out of the loss (use the R, G, B channels) or pass dL/d(RGB) of shape (H, W, 3)",
        ));
    }
    Ok(Image { width, height, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_that_do_not_fit_are_refused_with_both_shapes_named() {
        let message = |r: Result<ArrayStack>| r.unwrap_err().to_string();
        let rgba = vec![0.5f32; 2 * 3 * 4];
        let depth = vec![2.0f32; 6];
        assert!(message(stack_from_arrays(&rgba, &[2, 3, 3], &depth, &[2, 3], DepthKind::Z)).contains("(L, H, W, 4)"));
        let wrong = message(stack_from_arrays(&rgba, &[2, 3, 4], &depth, &[3, 2], DepthKind::Z));
        assert!(wrong.contains("shape (2, 3) to match layers of shape (2, 3, 4); got shape (3, 2)"), "{wrong}");
        let one = stack_from_arrays(&rgba, &[2, 3, 4], &depth, &[2, 3], DepthKind::Z).unwrap();
        assert!(one.single_image && one.stack.layers.len() == 1);
        assert!((one.stack.layers[0].disparity[0] - 0.5).abs() < 1e-7, "planar Z 2 is disparity 1/2");
        let (back_rgba, back_depth) = stack_to_arrays(one.stack, DepthKind::Z);
        assert_eq!((back_rgba, back_depth), (rgba, depth), "arrays -> stack -> arrays is the identity");
    }

    #[test]
    fn a_grad_output_is_rgb_or_rgba_with_zero_alpha_gradient() {
        let rgb = grad_output_from_array(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], &[1, 2, 3], 2, 1).unwrap();
        assert_eq!(rgb.pixels, vec![[1.0, 2.0, 3.0, 0.0], [4.0, 5.0, 6.0, 0.0]]);
        let alpha = grad_output_from_array(&[0.0, 0.0, 0.0, 1.0], &[1, 1, 4], 1, 1).unwrap_err().to_string();
        assert!(alpha.contains("alpha is not differentiated"), "{alpha}");
        let shape = grad_output_from_array(&[0.0; 3], &[1, 1, 3], 2, 1).unwrap_err().to_string();
        assert!(shape.contains("must have shape (1, 2, 3) or (1, 2, 4); got shape (1, 1, 3)"), "{shape}");
        assert!(grad_output_from_array(&[f32::NAN, 0.0, 0.0], &[1, 1, 3], 1, 1).is_err());
    }

    #[test]
    fn nan_colour_and_invalid_covered_depth_are_refused_as_in_a_file() {
        let mut rgba = vec![1.0f32; 2 * 2 * 4];
        rgba[5] = f32::NAN;
        let depth = vec![3.0f32; 4];
        let nan = stack_from_arrays(&rgba, &[1, 2, 2, 4], &depth, &[1, 2, 2], DepthKind::Z).unwrap_err().to_string();
        assert!(nan.contains("layer 'layer 0' channel 'G' has 1 NaN/Inf sample(s)"), "{nan}");
        let mut depth = depth;
        depth[2] = -1.0;
        let rgba = vec![1.0f32; 2 * 2 * 4];
        let bad = stack_from_arrays(&rgba, &[1, 2, 2, 4], &depth, &[1, 2, 2], DepthKind::Z).unwrap_err().to_string();
        assert!(bad.contains("1 covered pixel(s) with invalid depth"), "{bad}");
    }
}
