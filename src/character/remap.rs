//! Near/far blur multipliers and a maximum blur, as a remap of disparity.
//!
//! The CoC is linear in disparity (`r = K |d - d_f|`, [`crate::camera`]), so scaling the blur
//! on one side of the focal plane by `m` is exactly `d' = d_f + m (d - d_f)`, and clamping the
//! blur to `r_max` is exactly `|d' - d_f| <= r_max / K`. Any renderer then draws the new blur
//! with its own occlusion handling, unchanged.
use crate::camera::CocModel;
use crate::stack::LayerStack;
use crate::{Error, Result};

/// Blur multipliers in front of / behind the focal plane and an optional CoC radius clamp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlurRemap {
    /// Multiplier of the CoC of everything nearer than focus.
    pub near: f32,
    /// Multiplier of the CoC of everything farther than focus.
    pub far: f32,
    /// Largest CoC radius in pixels (`None`: unbounded).
    pub max_px: Option<f32>,
}

impl Default for BlurRemap {
    fn default() -> Self {
        Self { near: 1.0, far: 1.0, max_px: None }
    }
}

impl BlurRemap {
    pub fn validate(&self) -> Result<()> {
        for (name, m) in [("near blur multiplier", self.near), ("far blur multiplier", self.far)] {
            if !(m.is_finite() && m >= 0.0) {
                return Err(Error::invalid("blur remap", format!("{name} must be a non-negative number, got {m}")));
            }
        }
        match self.max_px {
            Some(r) if !(r.is_finite() && r >= 0.0) => {
                Err(Error::invalid("blur remap", format!("maximum blur must be a non-negative number of pixels, got {r}")))
            }
            _ => Ok(()),
        }
    }

    pub fn is_identity(&self) -> bool {
        self.near == 1.0 && self.far == 1.0 && self.max_px.is_none()
    }

    /// The remapped disparity of `d`. Monotonic non-decreasing in `d` (both multipliers are
    /// non-negative and the clamp is monotonic), so whatever was in front stays in front (or
    /// ties, where the clamp flattens both to the same blur): occlusion order is preserved.
    #[inline]
    pub fn disparity(&self, d: f32, coc: &CocModel) -> f32 {
        let rel = d - coc.focus_disparity;
        let mut scaled = if rel > 0.0 { self.near * rel } else { self.far * rel };
        if let Some(r_max) = self.max_px {
            if coc.k_px > 0.0 {
                let limit = r_max / coc.k_px;
                scaled = scaled.clamp(-limit, limit);
            }
        }
        coc.focus_disparity + scaled
    }

    /// Remaps every disparity of every layer in place.
    pub fn apply(&self, stack: &mut LayerStack, coc: &CocModel) {
        if self.is_identity() {
            return;
        }
        for layer in &mut stack.layers {
            layer.disparity.iter_mut().for_each(|d| *d = self.disparity(*d, coc));
        }
    }
}
