//! Highlight bloom: boosts bright values before the gather so bokeh balls read on LDR input.
//!
//! An 8-bit source clips every light source to 1.0, so after blurring a street lamp is no
//! brighter than a white wall and its bokeh ball vanishes. Boosting values near the clip
//! restores some of the lost dynamic range. Meant for LDR sources only: true HDR input
//! (EXR) already carries the highlight energy and needs none.
use crate::stack::LayerStack;
use crate::{Error, Result};

/// Colour is scaled by `1 + (gain - 1) * smoothstep(threshold, threshold + knee, v)`, where `v`
/// is the largest channel of the straight (un-premultiplied) colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bloom {
    pub threshold: f32,
    /// Multiplier reached at `threshold + knee` and above.
    pub gain: f32,
}

/// Default gain of `--bloom THRESHOLD` without `:GAIN`.
pub const DEFAULT_BLOOM_GAIN: f32 = 4.0;
/// Narrowest ramp, so a threshold at or above 1 still boosts smoothly (no hard edge).
const MIN_KNEE: f32 = 0.05;

impl Bloom {
    /// Parses `THRESHOLD[:GAIN]`.
    pub fn parse(spec: &str) -> Result<Self> {
        let number = |s: &str| {
            s.trim().parse::<f32>().map_err(|_| Error::invalid("bloom", format!("bloom '{spec}': '{s}' is not a number")))
        };
        let bloom = match spec.split_once(':') {
            Some((t, g)) => Bloom { threshold: number(t)?, gain: number(g)? },
            None => Bloom { threshold: number(spec)?, gain: DEFAULT_BLOOM_GAIN },
        };
        bloom.validate()?;
        Ok(bloom)
    }

    pub fn validate(&self) -> Result<()> {
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return Err(Error::invalid("bloom", format!("bloom threshold must be a non-negative number, got {}", self.threshold)));
        }
        if !(self.gain.is_finite() && self.gain >= 1.0) {
            return Err(Error::invalid("bloom", format!("bloom gain must be a number >= 1, got {}", self.gain)));
        }
        Ok(())
    }

    /// Width of the ramp: up to the LDR clip at 1.0, at least [`MIN_KNEE`].
    fn knee(&self) -> f32 {
        (1.0 - self.threshold).max(MIN_KNEE)
    }

    /// The factor a pixel of straight-colour peak `v` is multiplied by.
    #[inline]
    pub fn factor(&self, v: f32) -> f32 {
        let t = ((v - self.threshold) / self.knee()).clamp(0.0, 1.0);
        1.0 + (self.gain - 1.0) * t * t * (3.0 - 2.0 * t)
    }

    /// Boosts one premultiplied pixel; alpha (coverage) is unchanged.
    #[inline]
    pub fn pixel(&self, p: [f32; 4]) -> [f32; 4] {
        if p[3] <= 0.0 {
            return p;
        }
        let peak = p[0].max(p[1]).max(p[2]) / p[3];
        let f = self.factor(peak);
        [p[0] * f, p[1] * f, p[2] * f, p[3]]
    }

    pub fn apply(&self, stack: &mut LayerStack) {
        for layer in &mut stack.layers {
            layer.rgba.pixels.iter_mut().for_each(|p| *p = self.pixel(*p));
        }
    }
}
