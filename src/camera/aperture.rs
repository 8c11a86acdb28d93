//! Aperture shapes: the lens term `K(y, x)` of the rendering equation.
//!
//! Shapes are expressed as a *gauge*: a norm whose unit ball is the aperture. The soft scatter
//! test of a renderer compares `gauge(x - y)` with the CoC radius exactly where a disk compares
//! the Euclidean distance, so polygon edges stay as soft (and as differentiable) as the disk's.
//! A custom kernel image is a weight sampled inside the disk instead.
//!
//! Orientation: with the thin-lens/pinhole model, a point nearer than focus projects the
//! aperture mirrored through its centre, a farther one upright. [`Aperture::to_aperture_coords`]
//! applies that flip so odd-bladed bokeh turns over across the focal plane as in a real lens.
use std::f32::consts::PI;
use std::path::Path;

use crate::{Error, Result};

#[derive(Clone, Debug, PartialEq, Default)]
pub enum Aperture {
    #[default]
    Disk,
    /// A regular polygon inscribed in the unit circle.
    Polygon {
        blades: u32,
        /// Rotation of the first blade edge's normal, radians.
        rotation: f32,
        /// 0 = straight blades, 1 = a disk.
        roundness: f32,
    },
    /// An ellipse inscribed in the unit circle: semi-axes 1 and `1 / squeeze`, the long axis
    /// at `rotation` (radians, from +u toward +v). The anamorphic aperture.
    Ellipse {
        squeeze: f32,
        rotation: f32,
    },
    /// The disk with a central obstruction of `inner` times its radius: a catadioptric
    /// (mirror) lens, whose bokeh is a ring. Its weight is [`ring_weight`]: the hole has the
    /// disk's own one-pixel soft edge, so a renderer needs no image of it.
    Ring {
        inner: f32,
    },
    /// The cat's-eye pupil an off-axis point sees through a vignetting lens: the unit disk
    /// clipped by a second unit disk shifted by `shift` (aperture radii), centred on their
    /// lens-shaped intersection, so the two disks sit at `-shift / 2` and `+shift / 2`. Convex
    /// and centrally symmetric, a gauge's unit ball ([`cats_eye_gauge`]).
    CatsEye {
        shift: [f32; 2],
    },
    /// `base` vignetted into the cat's-eye of [`crate::character::CatsEye`] in one render: the
    /// shift varies over the frame (`strength * position / half-diagonal`), so the shape is
    /// not one gauge. Only Dr.Bokeh's default model renders it (its gauge path resolves the
    /// shape of each 16 px receiver tile: for the disk the [`Aperture::CatsEye`] of
    /// `LensView::at_receiver`, for a straight-bladed polygon or the ellipse the clipped and
    /// recentred base of `camera/vignetted.rs`); the character controls hand it to no other
    /// renderer, and only bases that [`super::vignettes_in_one_pass`] (make one with
    /// [`Aperture::vignetted`]). Position-free uses (`gauge`, `relative_area`) see the frame
    /// centre's shape, the base.
    Vignetted {
        strength: f32,
        base: Box<Aperture>,
    },
    /// A custom kernel image, sampled over the CoC disk.
    Kernel(KernelImage),
}

/// Square, single-channel kernel covering `[-1, 1]^2` in aperture coordinates, peak 1.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelImage {
    pub size: usize,
    pub weights: Vec<f32>,
}

/// CoC radii (pixels) over which kernel-image weights fade in: below the first the kernel is
/// sub-pixel and acts as a point, above the second it is sampled as it is.
pub const KERNEL_FADE_PX: [f32; 2] = [0.5, 1.5];

/// The aperture as a shader reads it (push constants): `[shape, rotation (rad), parameter,
/// kernel (1 = sample the kernel buffer)]`, shape 0 = disk (or kernel image), 1 = ellipse
/// (parameter = squeeze), 2 = ring (parameter = inner radius), >= 3 = polygon of that many
/// blades (parameter = roundness), -1 = cat's-eye (`[-1, shift.x / 2, shift.y / 2, 0]`), -2 =
/// vignetted base (`[-2, strength, base shape, base rotation]`: the base's shape code, 0 for
/// the disk, 1 the ellipse, else the polygon's blades; the ellipse's squeeze travels with the
/// base's closed-form constants).
pub type ApertureGpu = [f32; 4];

/// The GPU form's shape code of [`Aperture::CatsEye`].
pub const CATS_EYE_SHAPE: f32 = -1.0;

/// The GPU form's shape code of [`Aperture::Vignetted`].
pub const VIGNETTED_SHAPE: f32 = -2.0;

impl Aperture {
    pub fn polygon(blades: u32, rotation_deg: f32, roundness: f32) -> Result<Self> {
        if !(3..=16).contains(&blades) {
            return Err(Error::invalid("aperture", format!("a polygon aperture needs 3 to 16 blades, got {blades}")));
        }
        if !(0.0..=1.0).contains(&roundness) {
            return Err(Error::invalid("aperture", format!("aperture roundness must be in [0, 1], got {roundness}")));
        }
        if !rotation_deg.is_finite() {
            return Err(Error::invalid("aperture", "aperture rotation must be finite"));
        }
        // An n-gon is unchanged by a turn of 360/n degrees. Reducing here (in f64) keeps the
        // gauge's angle arithmetic in range: a huge rotation (found by fuzzing:
        // 2.2e21 degrees) otherwise loses every bit of the angle and the gauge went negative.
        let sector_deg = 360.0 / blades as f64;
        let rotation = (rotation_deg as f64).rem_euclid(sector_deg).to_radians() as f32;
        Ok(Aperture::Polygon { blades, rotation, roundness })
    }

    /// The anamorphic aperture: an ellipse `squeeze` times wider than tall, its long axis at
    /// `rotation_deg` (the polygon's convention: from +u toward +v; `rotation=90` gives the tall
    /// ovals of a desqueezed anamorphic plate).
    pub fn anamorphic(squeeze: f32, rotation_deg: f32) -> Result<Self> {
        if !(squeeze.is_finite() && (1.0..=8.0).contains(&squeeze)) {
            return Err(Error::invalid("aperture", format!(
                "anamorphic squeeze must be in [1, 8] (use rotation=90 for tall ovals), got {squeeze}"
            )));
        }
        if !rotation_deg.is_finite() {
            return Err(Error::invalid("aperture", "anamorphic rotation must be finite"));
        }
        // An ellipse is unchanged by a half turn (reduced as the polygon's rotation is).
        let rotation = (rotation_deg as f64).rem_euclid(180.0).to_radians() as f32;
        Ok(Aperture::Ellipse { squeeze, rotation })
    }

    /// `base` vignetted into a cat's-eye of `strength` in one render ([`Aperture::Vignetted`]),
    /// or `None` for a base that keeps the node grid ([`super::vignettes_in_one_pass`]).
    pub fn vignetted(base: &Aperture, strength: f32) -> Option<Self> {
        super::vignettes_in_one_pass(base).then(|| Aperture::Vignetted { strength, base: Box::new(base.clone()) })
    }

    /// The catadioptric aperture: the disk less a central obstruction of `inner` x its radius.
    pub fn ring(inner: f32) -> Result<Self> {
        if !(inner.is_finite() && (0.0..=0.9).contains(&inner)) {
            return Err(Error::invalid("aperture", format!("ring inner radius must be in [0, 0.9], got {inner}")));
        }
        Ok(Aperture::Ring { inner })
    }

    /// The cat's-eye pupil of a disk aperture vignetted by a disk shifted by `shift` (aperture
    /// radii; shorter than 1.9: at 2 the disks only touch and no light passes).
    pub fn cats_eye(shift: [f32; 2]) -> Result<Self> {
        let length = shift[0].hypot(shift[1]);
        if !(length.is_finite() && length < 1.9) {
            return Err(Error::invalid("aperture", format!("cat's-eye shift must be shorter than 1.9 aperture radii, got {length}")));
        }
        Ok(Aperture::CatsEye { shift })
    }

    /// Parses the CLI form: `disk`, `polygon:BLADES[:rotation=DEG][:roundness=R]`,
    /// `anamorphic:SQUEEZE[:rotation=DEG]` (an ellipse SQUEEZE times wider than tall),
    /// `ring:INNER` (catadioptric: central obstruction of INNER x the radius), `image:FILE`.
    pub fn parse(spec: &str) -> Result<Self> {
        let mut parts = spec.split(':');
        match parts.next().unwrap_or("") {
            "disk" if parts.next().is_none() => Ok(Aperture::Disk),
            "polygon" => {
                let blades = parts
                    .next()
                    .and_then(|b| b.parse::<u32>().ok())
                    .ok_or_else(|| Error::invalid("aperture", format!("aperture '{spec}': expected polygon:BLADES, e.g. polygon:6")))?;
                let (mut rotation, mut roundness) = (0.0f32, 0.0f32);
                for (key, value) in options(spec, parts)? {
                    match key {
                        "rotation" => rotation = value,
                        "roundness" => roundness = value,
                        _ => return Err(Error::invalid("aperture", format!("aperture '{spec}': unknown option '{key}' (rotation, roundness)"))),
                    }
                }
                Aperture::polygon(blades, rotation, roundness)
            }
            "anamorphic" => {
                let squeeze = leading_number(spec, parts.next(), "anamorphic:SQUEEZE, e.g. anamorphic:2")?;
                let mut rotation = 0.0f32;
                for (key, value) in options(spec, parts)? {
                    match key {
                        "rotation" => rotation = value,
                        _ => return Err(Error::invalid("aperture", format!("aperture '{spec}': unknown option '{key}' (rotation)"))),
                    }
                }
                Aperture::anamorphic(squeeze, rotation)
            }
            "ring" => {
                let inner = leading_number(spec, parts.next(), "ring:INNER, e.g. ring:0.5")?;
                if parts.next().is_some() {
                    return Err(Error::invalid("aperture", format!("aperture '{spec}': ring takes only the inner radius")));
                }
                Aperture::ring(inner)
            }
            "image" => {
                let path: String = parts.collect::<Vec<_>>().join(":");
                if path.is_empty() {
                    return Err(Error::invalid("aperture", "aperture 'image:FILE' needs a file"));
                }
                Ok(Aperture::Kernel(KernelImage::load(Path::new(&path))?))
            }
            _ => Err(Error::invalid("aperture", format!(
                "unknown aperture '{spec}': use disk, polygon:BLADES[:rotation=DEG][:roundness=R], \
                 anamorphic:SQUEEZE[:rotation=DEG], ring:INNER or image:FILE"
            ))),
        }
    }

    /// Maps a pixel offset `x - y` from a source of signed relative disparity `d` into
    /// aperture coordinates (mirrored for sources nearer than focus).
    #[inline]
    pub fn to_aperture_coords(dx: f32, dy: f32, relative_disparity: f32) -> (f32, f32) {
        if relative_disparity > 0.0 {
            (-dx, -dy)
        } else {
            (dx, dy)
        }
    }

    /// The aperture's gauge of an offset in aperture coordinates: the radius of the scaled
    /// aperture whose boundary passes through it. Euclidean length for disks and kernels.
    #[inline]
    pub fn gauge(&self, u: f32, v: f32) -> f32 {
        match *self {
            Aperture::Polygon { blades, rotation, roundness } => {
                polygon_gauge(u, v, blades as f32, rotation, roundness)
            }
            Aperture::Ellipse { squeeze, rotation } => ellipse_gauge(u, v, squeeze, rotation),
            Aperture::CatsEye { shift } => cats_eye_gauge(u, v, [0.5 * shift[0], 0.5 * shift[1]]),
            Aperture::Vignetted { ref base, .. } => base.gauge(u, v),
            _ => (u * u + v * v).sqrt(),
        }
    }

    /// Weight of the lens at normalised aperture coordinates (|(u,v)| <= 1 is the CoC): the
    /// shape at unit size, without the pixel-scale soft edges of [`Self::kernel_weight`].
    #[inline]
    pub fn weight(&self, u: f32, v: f32) -> f32 {
        match self {
            Aperture::Kernel(kernel) => kernel.sample(u, v),
            Aperture::Ring { inner } if u * u + v * v < inner * inner => 0.0,
            _ => 1.0,
        }
    }

    /// Area of the unit aperture relative to the unit disk (energy normalisation).
    pub fn relative_area(&self) -> f32 {
        match self {
            Aperture::Disk => 1.0,
            &Aperture::Polygon { blades, roundness, .. } => {
                let n = blades as f32;
                // Area of the unit-gauge ball, from the mean of 1/gauge^2 over directions.
                let samples = 4096;
                let mut sum = 0.0f64;
                for i in 0..samples {
                    let t = (i as f32 + 0.5) / samples as f32 * 2.0 * PI;
                    let g = polygon_gauge(t.cos(), t.sin(), n, 0.0, roundness);
                    sum += 1.0 / (g as f64 * g as f64);
                }
                (sum / samples as f64) as f32
            }
            // The ellipse's area pi * 1 * (1 / squeeze).
            &Aperture::Ellipse { squeeze, .. } => 1.0 / squeeze,
            &Aperture::Ring { inner } => 1.0 - inner * inner,
            Aperture::Vignetted { base, .. } => base.relative_area(),
            // Two unit disks whose centres are d apart overlap in 2 acos(d/2) - (d/2) sqrt(4 - d^2).
            &Aperture::CatsEye { shift } => {
                let half = 0.5 * shift[0].hypot(shift[1]) as f64;
                ((2.0 * half.acos() - half * (4.0 - 4.0 * half * half).sqrt()) / std::f64::consts::PI) as f32
            }
            Aperture::Kernel(kernel) => kernel.mean_over_disk(),
        }
    }

    /// Whether the shape is a gauge's unit ball (disk, polygon, ellipse): weight 1 inside,
    /// 0 outside, so a renderer needs only the gauge.
    pub fn is_gauge_shape(&self) -> bool {
        !matches!(self, Aperture::Kernel(_) | Aperture::Ring { .. })
    }

    /// Weight of the kernel image at the offset `(u, v)` (aperture coordinates, pixels) from a
    /// source whose CoC has radius `r` pixels: the image spans the soft disk of radius
    /// `r + 1/2` and fades in over [`KERNEL_FADE_PX`] of CoC, since a kernel smaller than a
    /// pixel cannot be resolved and integrates to a point. The ring's [`ring_weight`]; 1 for
    /// disks, polygons and ellipses (their shape is the gauge). Mirrors
    /// `aperture_kernel_weight` in `glsl/common/aperture.glsl`.
    #[inline]
    pub fn kernel_weight(&self, u: f32, v: f32, r: f32) -> f32 {
        match self {
            &Aperture::Ring { inner } => ring_weight((u * u + v * v).sqrt(), r, inner),
            Aperture::Kernel(kernel) => {
                let scale = 1.0 / (r + 0.5);
                1.0 + (kernel.sample(u * scale, v * scale) - 1.0) * kernel_fade(r)
            }
            _ => 1.0,
        }
    }

    /// The kernel image as a shader's kernel buffer: `(side, texels)`, side 0 and one dummy
    /// texel without a kernel (Vulkan buffers cannot be empty).
    pub fn kernel_texels(&self) -> (usize, Vec<f32>) {
        match self {
            Aperture::Kernel(kernel) => (kernel.size, kernel.weights.clone()),
            _ => (0, vec![0.0]),
        }
    }

    pub fn gpu_params(&self) -> ApertureGpu {
        match *self {
            Aperture::Disk => [0.0, 0.0, 1.0, 0.0],
            Aperture::Polygon { blades, rotation, roundness } => [blades as f32, rotation, roundness, 0.0],
            Aperture::Ellipse { squeeze, rotation } => [1.0, rotation, squeeze, 0.0],
            Aperture::Ring { inner } => [2.0, 0.0, inner, 0.0],
            Aperture::CatsEye { shift } => [CATS_EYE_SHAPE, 0.5 * shift[0], 0.5 * shift[1], 0.0],
            Aperture::Vignetted { strength, ref base } => {
                let [shape, rotation, ..] = base.gpu_params();
                [VIGNETTED_SHAPE, strength, shape, rotation]
            }
            Aperture::Kernel(_) => [0.0, 0.0, 1.0, 1.0],
        }
    }
}

/// The `key=value` options after an aperture's leading parameter.
fn options<'a>(spec: &str, parts: impl Iterator<Item = &'a str>) -> Result<Vec<(&'a str, f32)>> {
    parts
        .map(|option| {
            let (key, value) = option.split_once('=').ok_or_else(|| {
                Error::invalid("aperture", format!("aperture '{spec}': option '{option}' is not key=value"))
            })?;
            let value: f32 = value
                .parse()
                .map_err(|_| Error::invalid("aperture", format!("aperture '{spec}': '{value}' is not a number")))?;
            Ok((key, value))
        })
        .collect()
}

/// The number right after an aperture's name (`anamorphic:2`, `ring:0.5`).
fn leading_number(spec: &str, part: Option<&str>, expected: &str) -> Result<f32> {
    part.and_then(|p| p.parse::<f32>().ok())
        .ok_or_else(|| Error::invalid("aperture", format!("aperture '{spec}': expected {expected}")))
}

/// Gauge of a regular `n`-gon inscribed in the unit circle, blended toward the disk by
/// `roundness`. Mirrors `aperture_gauge` in `glsl/common/aperture.glsl`.
#[inline]
pub fn polygon_gauge(u: f32, v: f32, n: f32, rotation: f32, roundness: f32) -> f32 {
    let length = (u * u + v * v).sqrt();
    let sector = 2.0 * PI / n;
    // Angle to the nearest edge normal, folded into [-sector/2, sector/2].
    let theta = v.atan2(u) - rotation;
    let folded = theta - sector * (theta / sector).round();
    let poly = length * folded.cos() / (PI / n).cos();
    poly + (length - poly) * roundness
}

/// Weight of the ring aperture at distance `g` (pixels) from the centre of a CoC of radius
/// `r`: the obstruction is a disk of radius `inner * r` with the outer rim's one-pixel Hermite
/// edge (0 up to `inner r - 1/2`, 1 from `inner r + 1/2`), faded in over [`KERNEL_FADE_PX`]
/// as kernel images are (a sub-pixel ring integrates to a point). Mirrors
/// `aperture_ring_weight` in `glsl/common/aperture.glsl` and `math::ring_weight` (f64).
#[inline]
pub fn ring_weight(g: f32, r: f32, inner: f32) -> f32 {
    1.0 - kernel_fade(r) * (1.0 - hermite(g - (inner * r - 0.5)))
}

/// How far a kernel image or the ring has faded in at CoC radius `r` ([`KERNEL_FADE_PX`]).
#[inline]
fn kernel_fade(r: f32) -> f32 {
    let [start, end] = KERNEL_FADE_PX;
    hermite((r - start) / (end - start))
}

/// GLSL's `smoothstep(0, 1, t)`: the Hermite ramp, exactly 0 below 0 and 1 above 1.
#[inline]
fn hermite(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Gauge of the cat's-eye: the intersection of the unit disks centred at `a` and `-a`
/// (`|a| < 1`). A disk centred at `a` has gauge t solving `|p / t - a| = 1`, i.e.
/// `t = (-p.a + sqrt((p.a)^2 + k |p|^2)) / k` with `k = 1 - |a|^2`; an intersection's gauge
/// is the larger one, `(|p.a| + sqrt((p.a)^2 + k |p|^2)) / k`. Mirrors `aperture_cats_eye_gauge`
/// in `glsl/common/aperture.glsl`.
#[inline]
pub fn cats_eye_gauge(u: f32, v: f32, a: [f32; 2]) -> f32 {
    let k = 1.0 - (a[0] * a[0] + a[1] * a[1]);
    let q = (u * a[0] + v * a[1]).abs();
    (q + (q * q + k * (u * u + v * v)).sqrt()) / k
}

/// Gauge of the ellipse with semi-axes 1 (at `rotation` from +u toward +v) and `1 / squeeze`.
/// Mirrors `aperture_ellipse_gauge` in `glsl/common/aperture.glsl`.
#[inline]
pub fn ellipse_gauge(u: f32, v: f32, squeeze: f32, rotation: f32) -> f32 {
    let (s, c) = rotation.sin_cos();
    let along = u * c + v * s;
    let across = (v * c - u * s) * squeeze;
    (along * along + across * across).sqrt()
}

impl KernelImage {
    /// Loads a kernel from a greyscale/RGB image (luminance), normalised to a peak of 1 and
    /// resampled to a square.
    pub fn load(path: &Path) -> Result<Self> {
        let img = image::open(path)
            .map_err(|e| Error::input(path, format!("cannot read aperture kernel image: {e}")))?
            .to_luma32f();
        let size = img.width().max(img.height()).clamp(8, 256) as usize;
        let resized = image::imageops::resize(&img, size as u32, size as u32, image::imageops::FilterType::Triangle);
        Self::from_weights(size, resized.into_raw()).map_err(|e| Error::input(path, e.to_string()))
    }

    pub fn from_weights(size: usize, mut weights: Vec<f32>) -> Result<Self> {
        if size == 0 || weights.len() != size * size {
            return Err(Error::invalid("aperture", "kernel image must be square and non-empty"));
        }
        let peak = weights.iter().cloned().fold(0.0f32, f32::max);
        if !(peak > 0.0 && peak.is_finite()) {
            return Err(Error::invalid("aperture", "kernel image is black (or not finite): the aperture would pass no light"));
        }
        weights.iter_mut().for_each(|w| *w = (*w / peak).max(0.0));
        let kernel = Self { size, weights };
        // Renderers sample the kernel over the CoC disk only: light in the corners never passes.
        if kernel.mean_over_disk() <= 0.0 {
            return Err(Error::invalid("aperture", "kernel image is black inside its inscribed circle: the aperture would pass no light"));
        }
        Ok(kernel)
    }

    /// Bilinear sample at `(u, v)` in `[-1, 1]^2`; zero outside ([`bilinear_kernel_sample`]).
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        bilinear_kernel_sample(&self.weights, self.size, u, v)
    }

    fn mean_over_disk(&self) -> f32 {
        let (mut sum, mut count) = (0.0f64, 0usize);
        for j in 0..self.size {
            for i in 0..self.size {
                let u = (i as f32 + 0.5) / self.size as f32 * 2.0 - 1.0;
                let v = (j as f32 + 0.5) / self.size as f32 * 2.0 - 1.0;
                if u * u + v * v <= 1.0 {
                    sum += self.sample(u, v) as f64;
                    count += 1;
                }
            }
        }
        (sum / count.max(1) as f64) as f32
    }
}

/// Bilinear sample of a `size x size` kernel image at `(u, v)` in `[-1, 1]^2`, texel centres at
/// `(i + 1/2) / size`; zero outside. One body for the f32 image the shaders sample
/// ([`KernelImage::sample`]) and the f64 CPU reference of Dr.Bokeh's lens term
/// (`render::drbokeh::math::kernel_sample`): the same operations in the same order.
pub fn bilinear_kernel_sample<T: num_traits::Float>(weights: &[T], size: usize, u: T, v: T) -> T {
    let constant = |value: f64| T::from(value).expect("a float holds the sample's constants");
    let (half, one) = (constant(0.5), T::one());
    let n = constant(size as f64);
    let fx = (u * half + half) * n - half;
    let fy = (v * half + half) * n - half;
    if !(fx > -one && fy > -one && fx < n && fy < n) {
        return T::zero();
    }
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let at = |x: T, y: T| -> T {
        if x < T::zero() || y < T::zero() || x >= n || y >= n {
            T::zero()
        } else {
            weights[y.to_usize().unwrap_or(0) * size + x.to_usize().unwrap_or(0)]
        }
    };
    let top = at(x0, y0) * (one - tx) + at(x0 + one, y0) * tx;
    let bottom = at(x0, y0 + one) * (one - tx) + at(x0 + one, y0 + one) * tx;
    top * (one - ty) + bottom * ty
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_gauge_is_euclidean() {
        assert!((Aperture::Disk.gauge(3.0, 4.0) - 5.0).abs() < 1e-6);
    }

    #[test]
    fn polygon_vertices_lie_on_the_unit_circle_and_edges_inside() {
        let hex = Aperture::polygon(6, 0.0, 0.0).unwrap();
        // Edge normal at angle 0: the edge midpoint is at distance cos(pi/6) and has gauge 1.
        let mid = (PI / 6.0).cos();
        assert!((hex.gauge(mid, 0.0) - 1.0).abs() < 1e-5);
        // A vertex (angle pi/6) at radius 1 has gauge 1.
        let (s, c) = (PI / 6.0).sin_cos();
        assert!((hex.gauge(c, s) - 1.0).abs() < 1e-5);
        // A fully round polygon is the disk.
        let round = Aperture::polygon(6, 0.0, 1.0).unwrap();
        assert!((round.gauge(0.3, 0.4) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn polygon_area_matches_closed_form() {
        // Regular n-gon inscribed in the unit circle: (n/2) sin(2 pi / n), relative to pi.
        for n in [3u32, 5, 8] {
            let ap = Aperture::polygon(n, 0.0, 0.0).unwrap();
            let expected = 0.5 * n as f32 * (2.0 * PI / n as f32).sin() / PI;
            assert!((ap.relative_area() - expected).abs() < 2e-3, "n={n}");
        }
    }

    #[test]
    fn parse_accepts_documented_forms_and_refuses_others() {
        assert_eq!(Aperture::parse("disk").unwrap(), Aperture::Disk);
        let p = Aperture::parse("polygon:5:rotation=90:roundness=0.25").unwrap();
        // 90 degrees is 18 degrees for a pentagon (its symmetry is 72 degrees).
        assert_eq!(p, Aperture::Polygon { blades: 5, rotation: 18f64.to_radians() as f32, roundness: 0.25 });
        for bad in ["", "polygon", "polygon:2", "polygon:6:spin=3", "polygon:6:roundness=2", "hexagon", "image:"] {
            assert!(Aperture::parse(bad).is_err(), "{bad}");
        }
    }

    /// Fuzzing regression (fuzz/artifacts/params): a huge rotation gave a negative gauge.
    #[test]
    fn polygon_rotation_is_reduced_by_the_symmetry_and_huge_rotations_stay_valid() {
        let huge = Aperture::parse("polygon:6:rotation=22222222222222:rotation=2222222222222022222225").unwrap();
        for (u, v) in [(0.6, -0.3), (-0.2, 0.9), (1.0, 0.0)] {
            let gauge = huge.gauge(u, v);
            // The gauge of a hexagon lies between its inradius ratio and 1 times the radius.
            let length = (u * u + v * v as f32).sqrt();
            assert!(gauge >= length - 1e-6 && gauge <= length / (PI / 6.0).cos() + 1e-5, "({u}, {v}): {gauge}");
        }
        // Turning by the symmetry angle changes nothing.
        let a = Aperture::polygon(6, 10.0, 0.0).unwrap();
        let b = Aperture::polygon(6, 70.0, 0.0).unwrap();
        assert!((a.gauge(0.6, -0.3) - b.gauge(0.6, -0.3)).abs() < 1e-6);
    }

    #[test]
    fn kernel_images_must_pass_light_inside_the_disk() {
        // Light only in the corners of the square never reaches a renderer (it samples the
        // inscribed disk): refused when the kernel is made, not discovered as 0/0 later.
        let corners: Vec<f32> = (0..64).map(|i| if i == 0 || i == 63 { 1.0 } else { 0.0 }).collect();
        assert!(KernelImage::from_weights(8, corners).is_err());
        assert!(KernelImage::from_weights(8, vec![1.0; 64]).is_ok());
    }

    #[test]
    fn kernel_weight_fades_in_above_a_pixel_of_coc_and_is_one_without_a_kernel() {
        let ring = Aperture::parse("ring:0.6").unwrap();
        // Sub-pixel CoC: the kernel cannot be resolved, the weight is a point's (1).
        assert_eq!(ring.kernel_weight(0.0, 0.0, 0.4), 1.0);
        assert_eq!(ring.kernel_weight(0.0, 0.0, 10.0), 0.0, "the obstruction at full size");
        assert!(ring.kernel_weight(8.0, 0.0, 10.0) > 0.99, "the annulus at full size");
        assert_eq!(Aperture::polygon(6, 0.0, 0.0).unwrap().kernel_weight(0.0, 0.0, 10.0), 1.0);
    }

    #[test]
    fn the_ring_hole_has_the_rims_one_pixel_edge_and_passes_the_annulus_area() {
        let ring = Aperture::ring(0.5).unwrap();
        let r = 20.0;
        // The obstruction's edge is centred on inner * r = 10 px, a pixel wide.
        assert_eq!(ring.kernel_weight(9.5, 0.0, r), 0.0);
        assert!((ring.kernel_weight(0.0, 10.0, r) - 0.5).abs() < 1e-6);
        assert_eq!(ring.kernel_weight(6.0, 8.7, r), 1.0);
        assert_eq!(ring.weight(0.3, 0.3), 0.0);
        assert_eq!(ring.weight(0.5, 0.3), 1.0);
        assert!((ring.relative_area() - 0.75).abs() < 1e-6);
        assert!(!ring.is_gauge_shape(), "the hole is not a gauge's unit ball");
        for bad in ["ring", "ring:-0.1", "ring:0.95", "ring:0.5:0.2"] {
            assert!(Aperture::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_cats_eye_is_the_intersection_of_two_disks_centred_on_it() {
        let shift = [0.8f32, -0.6]; // |shift| = 1
        let eye = Aperture::cats_eye(shift).unwrap();
        let a = [0.4f32, -0.3];
        // On the rim of the disk at +a where it lies inside the disk at -a, and vice versa.
        for angle in [2.0f32, 2.5, 3.0] {
            let (s, c) = angle.sin_cos();
            let (u, v) = (a[0] + c, a[1] + s);
            let other = (u + a[0]).hypot(v + a[1]);
            if other <= 1.0 {
                assert!((eye.gauge(u, v) - 1.0).abs() < 1e-5, "angle {angle}: {}", eye.gauge(u, v));
                assert!((eye.gauge(-u, -v) - 1.0).abs() < 1e-5, "centrally symmetric");
            }
        }
        // Gauges scale: twice as far, twice the gauge; the origin is inside.
        assert!((eye.gauge(0.2, 0.1) * 2.0 - eye.gauge(0.4, 0.2)).abs() < 1e-6);
        // Area: the closed form against counting a fine grid.
        let n = 800;
        let inside = (0..n * n)
            .filter(|i| {
                let (u, v) = ((i % n) as f32 / n as f32 * 2.0 - 1.0, (i / n) as f32 / n as f32 * 2.0 - 1.0);
                eye.gauge(u + 1.0 / n as f32, v + 1.0 / n as f32) <= 1.0
            })
            .count();
        let counted = inside as f32 * 4.0 / (n * n) as f32 / PI;
        assert!((eye.relative_area() - counted).abs() < 2e-3, "{} vs {counted}", eye.relative_area());
        assert!(Aperture::cats_eye([1.5, 1.5]).is_err(), "no light passes");
    }

    #[test]
    fn near_sources_project_a_mirrored_aperture() {
        assert_eq!(Aperture::to_aperture_coords(1.0, 2.0, 0.5), (-1.0, -2.0));
        assert_eq!(Aperture::to_aperture_coords(1.0, 2.0, -0.5), (1.0, 2.0));
    }
}
