//! Lens character and artist controls (issue 12), on top of any rendering method and without
//! touching its shaders: every control is either a remap of the input (blur multipliers and
//! clamp, focus pick, highlight bloom), a procedural aperture (the anamorphic ellipse, the
//! ring and the cat's-eye of a disk, a straight-bladed polygon or the ellipse are shapes of
//! [`crate::camera::Aperture`] with closed forms; the cat's-eye of any other aperture is a
//! kernel image), or a combination of several renders (chromatic aberration: one per channel;
//! cat's-eye: one per grid node, or one pass of [`crate::camera::Aperture::Vignetted`] for
//! those closed-form bases under Dr.Bokeh). Each piece is a CPU
//! function testable on its own.
pub mod bloom;
pub mod chromatic;
pub mod debug;
pub mod focus;
pub mod kernels;
pub mod remap;
pub mod sheet;
pub mod vignette;

use std::borrow::Cow;

pub use bloom::Bloom;
pub use chromatic::render_chromatic;
pub use debug::write_debug_views;
pub use focus::focus_disparity_at;
pub use remap::BlurRemap;
pub use vignette::{render_cats_eye, CatsEye};

use crate::camera::Aperture;
use crate::image::Image;
use crate::render::drbokeh::RenderOptions;
use crate::camera::FocusField;
use crate::render::{Lens, Method, MethodSettings};
use crate::stack::LayerStack;
use crate::vk::Context;
use crate::{Error, Result};

/// Every control; `Character::default()` changes nothing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Character {
    pub remap: BlurRemap,
    /// Focus on the surface seen at this pixel `[x, y]` (overrides the lens's focus).
    pub focus_at: Option<[usize; 2]>,
    pub bloom: Option<Bloom>,
    /// Per-channel focus offsets in CoC pixels (R, G, B).
    pub chromatic: Option<[f32; 3]>,
    pub cats_eye: Option<CatsEye>,
}

impl Character {
    /// Checks every control's values (before any input is read).
    pub fn validate(&self) -> Result<()> {
        self.remap.validate()?;
        if let Some(bloom) = &self.bloom {
            bloom.validate()?;
        }
        if let Some(offsets) = self.chromatic {
            if offsets.iter().any(|o| !o.is_finite()) {
                return Err(Error::invalid("chromatic", format!("chromatic focus offsets must be finite numbers, got {offsets:?}")));
            }
        }
        if let Some(eye) = &self.cats_eye {
            eye.validate()?;
        }
        Ok(())
    }

    /// The stack and lens a renderer sees: focus picked, then disparities remapped (around the
    /// final focus), then highlights boosted. Borrowed unchanged when nothing applies.
    pub fn prepare<'a>(&self, stack: &'a LayerStack, lens: &Lens) -> Result<(Cow<'a, LayerStack>, Lens)> {
        self.prepare_framed(stack, lens, 0)
    }

    /// [`Self::prepare`] of a stack holding the frame `frame_margin` pixels inside its edge
    /// (the focus pixel is the frame's).
    pub fn prepare_framed<'a>(&self, stack: &'a LayerStack, lens: &Lens, frame_margin: usize) -> Result<(Cow<'a, LayerStack>, Lens)> {
        self.remap.validate()?;
        let mut lens = lens.clone();
        if let Some([x, y]) = self.focus_at {
            lens.coc.focus_disparity = focus_disparity_at(stack, x, y, frame_margin)?;
        }
        if self.remap.is_identity() && self.bloom.is_none() {
            return Ok((Cow::Borrowed(stack), lens));
        }
        let mut owned = stack.clone();
        self.remap.apply(&mut owned, &lens.coc);
        if let Some(bloom) = &self.bloom {
            bloom.validate()?;
            bloom.apply(&mut owned);
        }
        Ok((Cow::Owned(owned), lens))
    }

    /// Renders a prepared stack with `render` (one call per needed render: x3 for chromatic
    /// aberration, x grid nodes for cat's-eye).
    pub fn render_prepared(
        &self,
        render: &dyn Fn(&LayerStack, &Lens) -> Result<Image>,
        stack: &LayerStack,
        lens: &Lens,
    ) -> Result<Image> {
        let vignetted = |s: &LayerStack, l: &Lens| match &self.cats_eye {
            Some(eye) => render_cats_eye(render, s, l, eye),
            None => render(s, l),
        };
        match self.chromatic {
            Some(offsets) => render_chromatic(&vignetted, stack, lens, offsets),
            None => vignetted(stack, lens),
        }
    }

    /// How many renders [`Self::render_prepared`] makes of `stack` through `lens` (progress
    /// displays count them): x3 for chromatic aberration, x grid nodes for cat's-eye.
    pub fn render_count(&self, stack: &LayerStack, lens: &Lens) -> usize {
        let channels = self.chromatic.map_or(1, |offsets| chromatic::chromatic_renders(lens, offsets));
        let nodes = self.cats_eye.as_ref().map_or(1, |eye| vignette::cats_eye_renders(eye, stack.width, stack.height));
        channels * nodes
    }

    /// Refuses the controls that assume one focal plane through the frame centre when the
    /// method renders another focus field (Virtual DSLR's tilt-shift or several planes).
    pub fn check_focus_field(&self, focus: &FocusField) -> Result<()> {
        let (tilt, planes) = match focus {
            FocusField::Plane => return Ok(()),
            FocusField::Tilt { .. } => (true, false),
            FocusField::Planes(_) => (false, true),
        };
        // A focus pick and the blur remap act on the centre's plane only. The chromatic focus
        // shift moves a tilted field as a whole (exact), but several planes ignore the lens's
        // single focus it moves. Cat's-eye renders crops, which would move a tilt's pivot (the
        // crop's centre); planes are absolute and do not mind.
        let controls = [
            (self.focus_at.is_some(), "`focus_at`", true),
            (!self.remap.is_identity(), "`near_blur`/`far_blur`/`max_blur`", true),
            (self.chromatic.is_some(), "`chromatic`", planes),
            (self.cats_eye.is_some(), "`cats_eye`", tilt),
        ];
        let conflicts: Vec<&str> = controls.iter().filter(|(on, _, conflicts)| *on && *conflicts).map(|c| c.1).collect();
        if conflicts.is_empty() {
            return Ok(());
        }
        let field = if tilt { "`tilt_shift`" } else { "`focal_planes`" };
        Err(Error::invalid("lens character", format!(
            "{} cannot be combined with {field}: they act on one focal plane through the frame centre; drop one of them",
            conflicts.join(", ")
        )))
    }

    /// Prepares and renders with `method` and its `settings`; returns the image and the stack
    /// and lens rendered (what the debug views describe).
    pub fn render<'a>(
        &self,
        method: Method,
        ctx: Option<&Context>,
        stack: &'a LayerStack,
        lens: &Lens,
        options: &RenderOptions,
        settings: &MethodSettings,
    ) -> Result<(Image, Cow<'a, LayerStack>, Lens)> {
        self.check_focus_field(settings.focus(method))?;
        let (prepared, lens) = self.prepare(stack, lens)?;
        let (look, lens) = self.for_method(method, &lens);
        let render = |s: &LayerStack, l: &Lens| method.render_with(ctx, s, l, options, settings);
        let image = look.render_prepared(&render, &prepared, &lens)?;
        Ok((image, prepared, lens))
    }

    /// The controls and lens `method` renders: a cat's-eye of a disk, a straight-bladed
    /// polygon or the anamorphic ellipse under Dr.Bokeh's default model is one render of
    /// [`Aperture::Vignetted`] (its gauge path takes each receiver tile's shape), so the node
    /// grid is dropped; every other method, model or base aperture (rounded blades, rings,
    /// kernel images) keeps the grid ([`render_cats_eye`]). [`Self::render_count`] of the
    /// result counts what [`Self::render`] does.
    pub fn for_method(&self, method: Method, lens: &Lens) -> (Character, Lens) {
        let one_pass = match &self.cats_eye {
            Some(eye) if method == Method::DrBokeh => Aperture::vignetted(&lens.aperture, eye.strength),
            _ => None,
        };
        match one_pass {
            Some(aperture) => (Character { cats_eye: None, ..self.clone() }, Lens { aperture, ..lens.clone() }),
            None => (self.clone(), lens.clone()),
        }
    }
}
