//! Optical vignetting (cat's-eye bokeh) as a position-dependent aperture, host-side.
//!
//! A disk, a straight-bladed polygon or the anamorphic ellipse under Dr.Bokeh's default model
//! needs none of this: it renders in one pass as [`Aperture::Vignetted`] (each receiver tile's
//! cat's-eye, `Character::for_method`). Every other aperture (rounded blades, rings, kernel
//! images) or method takes one shape per render, so the frame is rendered on a grid of `G x G`
//! nodes: node (i, j) sits at `(i / (G-1), j / (G-1))` of the frame (corners included) and
//! gets the cat's-eye kernel of its own position. Each output pixel blends the renders of its
//! four surrounding nodes with bilinear (tent) weights, which sum to 1. So the aperture is
//! piecewise constant per node and the seams are blended linearly; it is exact at the nodes
//! and a mix of the neighbouring shapes between them.
//!
//! Each node renders only the rectangle its tent covers, plus a halo wider than any CoC, so
//! every pixel it contributes sees all the sources a whole-frame render would.
use super::kernels::cats_eye;
use crate::camera::Aperture;
use crate::image::Image;
use crate::render::drbokeh::COMPAT_TAIL_PX;
use crate::render::Lens;
use crate::stack::{Layer, LayerStack};
use crate::tile_grid::Rect;
use crate::{Error, Result};

/// Nodes per side of the grid unless told otherwise: 16 renders covering ~4 frames in all.
pub const DEFAULT_GRID: usize = 4;

/// Cat's-eye strength: the clipping disk is shifted by `strength * p` aperture radii, with `p`
/// the position from the frame centre divided by the half diagonal (|p| = 1 at a corner).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CatsEye {
    pub strength: f32,
    /// Nodes per side (>= 2).
    pub grid: usize,
}

impl CatsEye {
    pub fn new(strength: f32) -> Result<Self> {
        let eye = Self { strength, grid: DEFAULT_GRID };
        eye.validate()?;
        Ok(eye)
    }

    pub fn validate(&self) -> Result<()> {
        // Two unit disks shifted by 2 radii share no area: no light would pass at a corner.
        if !(self.strength.is_finite() && (0.0..=1.5).contains(&self.strength)) {
            return Err(Error::invalid("cats-eye", format!("cat's-eye strength must be in [0, 1.5], got {}", self.strength)));
        }
        if self.grid < 2 {
            return Err(Error::invalid("cats-eye", "cat's-eye grid needs at least 2 nodes per side"));
        }
        Ok(())
    }

    /// Shift of the clipping disk at pixel `(x, y)` of a `width x height` frame.
    pub fn shift(&self, x: f32, y: f32, width: usize, height: usize) -> [f32; 2] {
        let (cx, cy) = ((width as f32 - 1.0) / 2.0, (height as f32 - 1.0) / 2.0);
        let half_diagonal = (cx * cx + cy * cy).sqrt().max(1.0);
        [self.strength * (x - cx) / half_diagonal, self.strength * (y - cy) / half_diagonal]
    }
}

/// How many renders [`render_cats_eye`] makes of a `width` x `height` frame: one per node.
pub fn cats_eye_renders(eye: &CatsEye, width: usize, height: usize) -> usize {
    nodes(width, eye.grid).len() * nodes(height, eye.grid).len()
}

/// Node positions along one axis of `n` pixels (first and last pixel included).
fn nodes(n: usize, grid: usize) -> Vec<f32> {
    let count = grid.min(n).max(1);
    if count == 1 {
        return vec![0.0];
    }
    (0..count).map(|i| i as f32 * (n - 1) as f32 / (count - 1) as f32).collect()
}

/// Tent weight of node `k` at coordinate `t`.
fn tent(nodes: &[f32], k: usize, t: f32) -> f32 {
    let here = nodes[k];
    if t < here {
        match k.checked_sub(1) {
            Some(prev) => ((t - nodes[prev]) / (here - nodes[prev])).max(0.0),
            None => 1.0,
        }
    } else {
        match nodes.get(k + 1) {
            Some(&next) => ((next - t) / (next - here)).max(0.0),
            None => 1.0,
        }
    }
}

/// Pixel span `[lo, hi)` where node `k`'s tent is non-zero.
fn span(nodes: &[f32], k: usize, n: usize) -> (usize, usize) {
    let lo = if k == 0 { 0 } else { nodes[k - 1].floor() as usize };
    let hi = nodes.get(k + 1).map_or(n, |&next| (next.ceil() as usize + 1).min(n));
    (lo, hi)
}

/// Renders `stack` through `lens` with cat's-eye vignetting, calling `render` once per node.
pub fn render_cats_eye(
    render: &dyn Fn(&LayerStack, &Lens) -> Result<Image>,
    stack: &LayerStack,
    lens: &Lens,
    eye: &CatsEye,
) -> Result<Image> {
    eye.validate()?;
    let (w, h) = (stack.width, stack.height);
    let (xs, ys) = (nodes(w, eye.grid), nodes(h, eye.grid));
    let (lo, hi) = stack.disparity_range();
    let halo = (lens.coc.max_radius(lo, hi).ceil() as f64 + COMPAT_TAIL_PX + 2.0) as usize;
    let mut out = Image::new(w, h);
    for (j, &ny) in ys.iter().enumerate() {
        for (i, &nx) in xs.iter().enumerate() {
            let shift = eye.shift(nx, ny, w, h);
            // A vignetted disk is a gauge shape of its own (the renderers' fast paths); other
            // apertures clipped by the disk become kernel images.
            let aperture = match lens.aperture {
                Aperture::Disk => Aperture::cats_eye(shift)?,
                _ => Aperture::Kernel(cats_eye(&lens.aperture, shift)?),
            };
            let node_lens = Lens { coc: lens.coc, aperture };
            let ((x0, x1), (y0, y1)) = (span(&xs, i, w), span(&ys, j, h));
            let read = Rect { x0: x0.saturating_sub(halo), y0: y0.saturating_sub(halo), x1: (x1 + halo).min(w), y1: (y1 + halo).min(h) };
            let part = render(&crop(stack, read)?, &node_lens)?;
            for y in y0..y1 {
                let wy = tent(&ys, j, y as f32);
                for x in x0..x1 {
                    let weight = wy * tent(&xs, i, x as f32);
                    if weight > 0.0 {
                        let p = part.get(x - read.x0, y - read.y0);
                        let o = &mut out.pixels[y * w + x];
                        (0..4).for_each(|c| o[c] += weight * p[c]);
                    }
                }
            }
        }
    }
    Ok(out)
}

/// The layers of `stack` cut to `rect`.
pub fn crop(stack: &LayerStack, rect: Rect) -> Result<LayerStack> {
    let layers = stack
        .layers
        .iter()
        .map(|layer| {
            let rgba = Image::from_fn(rect.width(), rect.height(), |x, y| layer.rgba.get(rect.x0 + x, rect.y0 + y));
            let disparity = (rect.y0..rect.y1)
                .flat_map(|y| layer.disparity[y * stack.width + rect.x0..y * stack.width + rect.x1].iter().copied())
                .collect();
            Layer { name: layer.name.clone(), rgba, disparity }
        })
        .collect();
    LayerStack::new(rect.width(), rect.height(), layers)
}
