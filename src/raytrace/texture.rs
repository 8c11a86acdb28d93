//! Procedural textures: premultiplied linear RGBA as a function of a surface's plane
//! coordinates. Nothing is downloaded; every texture is a small, deterministic function.
//!
//! Texture units: `(u, v)` with `u = x / scale`, `v = y / scale` for a hit at world `(x, y)`,
//! where a surface's `scale` is half the frame width at its reference depth. So `u` runs over
//! [-1, 1] across the frame and `v` over [-H/W, H/W] (downwards), at any resolution.
use std::fmt::Debug;
use std::sync::Arc;

use super::noise::fbm;
use super::shape::Shape;

pub type Rgba = [f32; 4];
pub type Rgb = [f32; 3];

pub trait Texture: Send + Sync + Debug {
    /// Premultiplied, linear RGBA at texture coordinates `(u, v)`; alpha is coverage.
    fn sample(&self, u: f32, v: f32) -> Rgba;
}

pub type TextureRef = Arc<dyn Texture>;

fn opaque(c: Rgb) -> Rgba {
    [c[0], c[1], c[2], 1.0]
}

fn mix(a: Rgb, b: Rgb, t: f32) -> Rgb {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t]
}

fn scaled(c: Rgb, s: f32) -> Rgb {
    [c[0] * s, c[1] * s, c[2] * s]
}

#[derive(Debug)]
pub struct Solid(pub Rgba);

impl Texture for Solid {
    fn sample(&self, _: f32, _: f32) -> Rgba {
        self.0
    }
}

/// Two colours mixed by fractal noise: skin, cloth, bark, foliage.
#[derive(Debug)]
pub struct Mottled {
    pub a: Rgb,
    pub b: Rgb,
    /// Noise features per texture unit.
    pub frequency: f32,
    pub seed: u32,
}

impl Texture for Mottled {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        let t = fbm(u * self.frequency, v * self.frequency, 5, self.seed);
        opaque(mix(self.a, self.b, (t - 0.2).clamp(0.0, 1.0) / 0.6))
    }
}

/// A checkerboard of period `period` texture units (one period = two squares).
#[derive(Debug)]
pub struct Checker {
    pub period: f32,
    pub a: Rgb,
    pub b: Rgb,
}

impl Texture for Checker {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        let cell = (2.0 * u / self.period).floor() as i64 + (2.0 * v / self.period).floor() as i64;
        opaque(if cell.rem_euclid(2) == 0 { self.a } else { self.b })
    }
}

/// Parallel stripes at `angle` radians; `duty` is the fraction of each period in colour `a`.
#[derive(Debug)]
pub struct Stripes {
    pub period: f32,
    pub angle: f32,
    pub duty: f32,
    pub a: Rgb,
    pub b: Rgb,
}

impl Texture for Stripes {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        let s = (u * self.angle.cos() + v * self.angle.sin()) / self.period;
        opaque(if s - s.floor() < self.duty { self.a } else { self.b })
    }
}

/// A procedural landscape "photograph": sky with clouds over a textured ground, a skyline of
/// blocks with lit windows between them. Detail at every scale from the frame to a pixel.
#[derive(Debug)]
pub struct Photo {
    pub sky_top: Rgb,
    pub sky_horizon: Rgb,
    pub ground: Rgb,
    pub buildings: Rgb,
    /// Horizon height in texture units (v grows downwards).
    pub horizon: f32,
    pub seed: u32,
}

impl Photo {
    fn sky(&self, u: f32, v: f32) -> Rgb {
        let t = ((v + 1.0) / (self.horizon + 1.0)).clamp(0.0, 1.0);
        let cloud = (fbm(u * 2.5, v * 6.0, 5, self.seed) - 0.45).max(0.0) * 1.6;
        mix(mix(self.sky_top, self.sky_horizon, t), [0.9, 0.9, 0.92], cloud.min(1.0))
    }

    /// Skyline block at `u`: its top (texture units) and a per-block shade.
    fn block(&self, u: f32) -> (f32, f32) {
        let cell = (u * 7.0).floor();
        let h = fbm(cell * 3.1, 0.5, 1, self.seed ^ 0xB10C);
        (self.horizon - 0.05 - 0.3 * h, 0.6 + 0.5 * h)
    }

    fn window_lit(&self, u: f32, v: f32) -> bool {
        let (wu, wv) = (u * 60.0, v * 45.0);
        let inside = wu - wu.floor() < 0.45 && wv - wv.floor() < 0.5;
        inside && fbm(wu.floor() * 1.7, wv.floor() * 1.3, 1, self.seed ^ 0x57) > 0.55
    }

    fn ground(&self, u: f32, v: f32) -> Rgb {
        let depth = (v - self.horizon).max(0.0) + 0.05;
        let detail = fbm(u * 3.0 / depth, v * 25.0 / depth.sqrt(), 5, self.seed ^ 0x6D);
        scaled(self.ground, 0.45 + 0.9 * detail)
    }
}

impl Texture for Photo {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        let (top, shade) = self.block(u);
        let c = if v >= self.horizon {
            self.ground(u, v)
        } else if v >= top {
            if self.window_lit(u, v) { [1.0, 0.85, 0.55] } else { scaled(self.buildings, shade) }
        } else {
            self.sky(u, v)
        };
        opaque(c)
    }
}

/// A textured fill restricted to a shape: the cut-out objects of the scenes.
#[derive(Debug)]
pub struct Cutout {
    pub shape: Shape,
    pub fill: TextureRef,
}

impl Texture for Cutout {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        if self.shape.covers(u, v) { self.fill.sample(u, v) } else { [0.0; 4] }
    }
}

/// Uniform partial transparency (a veil, tinted glass): premultiplied scaling of everything.
#[derive(Debug)]
pub struct Opacity {
    pub texture: TextureRef,
    pub alpha: f32,
}

impl Texture for Opacity {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        self.texture.sample(u, v).map(|c| c * self.alpha)
    }
}

/// Several textures in one plane, composited with premultiplied "over", front first.
#[derive(Debug)]
pub struct Over(pub Vec<TextureRef>);

impl Texture for Over {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        let mut acc = [0.0f32; 4];
        for texture in &self.0 {
            let c = texture.sample(u, v);
            let t = 1.0 - acc[3];
            for (a, c) in acc.iter_mut().zip(c) {
                *a += t * c;
            }
            if acc[3] >= 1.0 {
                break;
            }
        }
        acc
    }
}

/// Small HDR discs (street lights, specular glints): the sources of bokeh balls.
#[derive(Debug)]
pub struct Lights {
    /// Centre `(u, v)`, radius (texture units) and linear HDR colour (values 5-50).
    pub discs: Vec<([f32; 2], f32, Rgb)>,
}

impl Texture for Lights {
    fn sample(&self, u: f32, v: f32) -> Rgba {
        for &([cu, cv], r, c) in &self.discs {
            let (du, dv) = (u - cu, v - cv);
            if du * du + dv * dv <= r * r {
                return opaque(c);
            }
        }
        [0.0; 4]
    }
}

pub fn arc<T: Texture + 'static>(texture: T) -> TextureRef {
    Arc::new(texture)
}
