//! Scenes: textured planes in front of a physical camera.
//!
//! World frame: the pinhole (and the centre of the thin lens) at the origin, looking down +z,
//! x to the right and y *down*, so image rows and world y grow the same way. A surface is the
//! plane `z + slope . (x, y) = z0`; `slope = 0` is the fronto-parallel billboard of the
//! Dr.Bokeh benchmark, anything else a tilted plane with continuous depth. Along a pinhole
//! ray of direction `(tx, ty, 1)` its disparity is `(1 + slope . t) / z0`: linear in the image.
use crate::camera::PhysicalCamera;
use crate::{Error, Result};

use super::texture::TextureRef;

/// Most surfaces a scene may hold; keeps the per-ray hit list on the stack.
pub const MAX_SURFACES: usize = 16;

#[derive(Clone, Debug)]
pub struct Surface {
    pub name: String,
    /// Depth (metres) where the surface crosses the optical axis.
    pub z0: f32,
    /// Depth gradient: the plane is `z + slope[0] x + slope[1] y = z0`.
    pub slope: [f32; 2],
    /// Metres per texture unit (see [`super::texture`]).
    pub texture_scale: f32,
    pub texture: TextureRef,
}

impl Surface {
    /// A fronto-parallel billboard at depth `z`, texture unit = half the frame width there.
    pub fn billboard(name: &str, z: f32, camera: &PhysicalCamera, texture: TextureRef) -> Self {
        Self::tilted(name, z, [0.0, 0.0], camera, texture)
    }

    /// A tilted plane: disparity along the image is `(1 + slope . t) / z0`, `t` the pinhole
    /// ray's `(x/z, y/z)`. Texture unit = half the frame width at `z0`.
    pub fn tilted(name: &str, z0: f32, slope: [f32; 2], camera: &PhysicalCamera, texture: TextureRef) -> Self {
        let half_width = z0 * camera.sensor_width_mm / (2.0 * camera.focal_length_mm);
        Self { name: name.to_string(), z0, slope, texture_scale: half_width, texture }
    }

    /// Intersection of the ray `origin + s * dir` (origin on the lens plane z = 0) with this
    /// surface: `(depth z, texture u, texture v)`, or `None` if it misses or lies behind.
    #[inline]
    pub fn hit(&self, origin: [f32; 2], dir: [f32; 3]) -> Option<(f32, f32, f32)> {
        let denominator = dir[2] + self.slope[0] * dir[0] + self.slope[1] * dir[1];
        let numerator = self.z0 - self.slope[0] * origin[0] - self.slope[1] * origin[1];
        let s = numerator / denominator;
        if !(denominator > 0.0 && s > 0.0 && s.is_finite()) {
            return None;
        }
        let (x, y) = (origin[0] + s * dir[0], origin[1] + s * dir[1]);
        Some((s * dir[2], x / self.texture_scale, y / self.texture_scale))
    }

    /// Disparity (1/z) seen along the pinhole ray with direction `(tx, ty, 1)`; 0 if missed.
    pub fn pinhole_disparity(&self, t: [f32; 2]) -> f32 {
        ((1.0 + self.slope[0] * t[0] + self.slope[1] * t[1]) / self.z0).max(0.0)
    }
}

/// Where in a pixel the depth map (`GroundTruth::pinhole_depth`) is taken.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ZPass {
    /// The pixel centre: depth edges sit exactly where the colour's coverage crosses a half.
    #[default]
    PixelCentre,
    /// One anti-aliasing sample, picked per pixel, as Cycles writes its Z pass (one sample, jittered in
    /// the pixel): at an edge the depth label and the colour's majority disagree now and then,
    /// so a mixed pixel mostly of one surface may carry the other's depth (issue 22's held-out
    /// renders).
    OneSample,
}

/// A scene: surfaces listed front to back (by `z0`) and the camera that looks at them.
#[derive(Clone)]
pub struct Scene {
    pub name: String,
    pub description: String,
    pub camera: PhysicalCamera,
    /// Native resolution; `TraceOptions::scale` multiplies it.
    pub width: usize,
    pub height: usize,
    pub surfaces: Vec<Surface>,
    pub z_pass: ZPass,
}

/// The derived form, with `z_pass` only where it is not the default: the ground-truth cache
/// keys hash this text, so the scenes that keep the pixel-centre depth keep their keys.
impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("Scene");
        d.field("name", &self.name)
            .field("description", &self.description)
            .field("camera", &self.camera)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("surfaces", &self.surfaces);
        if self.z_pass != ZPass::default() {
            d.field("z_pass", &self.z_pass);
        }
        d.finish()
    }
}

impl Scene {
    pub fn validate(&self) -> Result<()> {
        self.camera.validate()?;
        if self.surfaces.is_empty() || self.surfaces.len() > MAX_SURFACES {
            return Err(Error::invalid("scene", format!("scene '{}' needs 1 to {MAX_SURFACES} surfaces", self.name)));
        }
        if self.width == 0 || self.height == 0 {
            return Err(Error::invalid("scene", format!("scene '{}' has an empty image size", self.name)));
        }
        for s in &self.surfaces {
            if !(s.z0 > 0.0 && s.z0.is_finite() && s.texture_scale > 0.0) {
                return Err(Error::invalid("scene", format!("surface '{}' must lie in front of the camera", s.name)));
            }
        }
        Ok(())
    }

    /// Image size at a scale factor (at least 1 x 1).
    pub fn size(&self, scale: f32) -> (usize, usize) {
        let dim = |n: usize| ((n as f32 * scale).round() as usize).max(1);
        (dim(self.width), dim(self.height))
    }

    /// Pinhole ray direction `(tx, ty)` (z = 1) through image point `(x, y)` in pixels of a
    /// `width x height` image; principal point at the image centre.
    pub fn ray_slope(&self, width: usize, height: usize, x: f32, y: f32) -> [f32; 2] {
        let f_px = self.camera.focal_length_px(width);
        [(x - width as f32 * 0.5) / f_px, (y - height as f32 * 0.5) / f_px]
    }

    /// Smallest and largest CoC radius (pixels, image `width` wide) over every surface as
    /// seen through the frame. Disparity is linear in the image, so the corners bound it.
    pub fn coc_range_px(&self, width: usize, height: usize) -> Result<(f32, f32)> {
        let coc = crate::camera::CocModel::from_physical(&self.camera, width)?;
        let corners = [(0.0, 0.0), (width as f32, 0.0), (0.0, height as f32), (width as f32, height as f32)];
        let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
        for s in &self.surfaces {
            let ds: Vec<f32> = corners.iter().map(|&(x, y)| s.pinhole_disparity(self.ray_slope(width, height, x, y))).collect();
            let (dmin, dmax) = ds.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &d| (a.min(d), b.max(d)));
            let crosses_focus = dmin <= coc.focus_disparity && coc.focus_disparity <= dmax;
            lo = lo.min(if crosses_focus { 0.0 } else { coc.radius(dmin).min(coc.radius(dmax)) });
            hi = hi.max(coc.max_radius(dmin, dmax));
        }
        Ok((lo, hi))
    }
}
