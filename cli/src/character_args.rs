//! Lens character flags of `lensblur render` (issue 12), parsed into the library's
//! [`Character`]; `--debug-out` writes the debug views after the render.
use std::path::PathBuf;

use anyhow::Context as _;
use lensblur::character::{chromatic, focus, Bloom, BlurRemap, CatsEye, Character};
use lensblur::job::Rendered;
use lensblur::stack::LayerStack;

#[derive(clap::Args, Clone, Debug)]
pub struct CharacterArgs {
    /// Multiply the blur of everything nearer than focus by M.
    #[arg(long, value_name = "M", default_value_t = 1.0, help_heading = "Lens character")]
    pub near_blur: f32,
    /// Multiply the blur of everything farther than focus by M.
    #[arg(long, value_name = "M", default_value_t = 1.0, help_heading = "Lens character")]
    pub far_blur: f32,
    /// Clamp the CoC radius to PX pixels.
    #[arg(long, value_name = "PX", help_heading = "Lens character")]
    pub max_blur: Option<f32>,
    /// Focus on the surface seen at pixel X,Y (front-most layer with alpha >= 0.5).
    #[arg(long, value_name = "X,Y", help_heading = "Lens character")]
    pub focus_at: Option<String>,
    /// Boost highlights above THRESHOLD by up to GAIN (default 4) before blurring (LDR input).
    #[arg(long, value_name = "THRESHOLD[:GAIN]", help_heading = "Lens character")]
    pub bloom: Option<String>,
    /// Longitudinal chromatic aberration: per-channel focus offsets in CoC pixels.
    #[arg(long, value_name = "R,G,B", allow_hyphen_values = true, help_heading = "Lens character")]
    pub chromatic: Option<String>,
    /// Cat's-eye (optical vignetting) strength in [0, 1.5]: bokeh narrows toward the corners.
    #[arg(long, value_name = "STRENGTH", help_heading = "Lens character")]
    pub cats_eye: Option<f32>,
    /// Write debug views (CoC, layers, focus peaking, per-layer visibility PNGs) into DIR.
    #[arg(long, value_name = "DIR", help_heading = "Lens character")]
    pub debug_out: Option<PathBuf>,
}

impl CharacterArgs {
    /// The library's [`Character`] these flags give (parsed here; the job checks the values).
    pub fn character(&self) -> anyhow::Result<Character> {
        Ok(Character {
            remap: BlurRemap { near: self.near_blur, far: self.far_blur, max_px: self.max_blur },
            focus_at: self.focus_at.as_deref().map(focus::parse_pixel).transpose().context("--focus-at")?,
            bloom: self.bloom.as_deref().map(Bloom::parse).transpose().context("--bloom")?,
            chromatic: self.chromatic.as_deref().map(chromatic::parse_offsets).transpose().context("--chromatic")?,
            cats_eye: self.cats_eye.map(CatsEye::new).transpose().context("--cats-eye")?,
        })
    }

    /// The `--debug-out` files `stack` would produce, each named by the flag; none without it.
    pub fn debug_view_paths(&self, stack: &LayerStack) -> Vec<PathBuf> {
        let Some(dir) = &self.debug_out else { return Vec::new() };
        lensblur::character::debug::debug_view_names(stack).into_iter().map(|name| dir.join(name)).collect()
    }

    /// Writes the `--debug-out` views of a render, if asked (after the device work is done and
    /// validated, like every other output).
    pub fn write_debug_views(&self, rendered: &Rendered, frame_margin: usize) -> anyhow::Result<()> {
        if let Some(dir) = &self.debug_out {
            let (stack, image) = (&rendered.prepared, &rendered.image);
            lensblur::character::write_debug_views(dir, stack, &rendered.lens, &rendered.focus, image, frame_margin)
                .context("--debug-out")?;
        }
        Ok(())
    }
}
