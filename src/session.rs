//! A resident renderer, for focus pulled interactively: the device opened once, each method's
//! pipelines prepared once, the input read once. Each render is a [`RenderJob`] (another
//! camera, aperture, lens character or method settings); only what the job changes is done
//! again. A stack whose layering depends on the camera (a flat RGB+Z image split by CoC, deep
//! samples clustered by it) is re-layered only when the render's circle-of-confusion model or
//! its layering options differ from the last one's; true layers are never re-layered. A session's render equals
//! the one-shot render of the same job: the same code runs on the same data.
use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::camera::{CameraHints, CocModel};
use crate::image::Image;
use crate::input::{InputOptions, LoadedInput, ReadInput};
use crate::job::RenderJob;
use crate::render::tiler::StackMemo;
use crate::render::{InputKind, Renderer};
use crate::vk::Context;
use crate::Result;

/// What one render of a session did and took.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct SessionRender {
    /// The stack was layered anew for this render (its camera changed the cut).
    pub relayered: bool,
    /// The method's renderer was prepared for this render (its first use in the session).
    pub prepared: bool,
    /// It rendered on the CPU: the session has no device, or a small frame on a CPU device.
    pub cpu: bool,
    /// Milliseconds: layering (0 when reused), rendering, and the whole call.
    pub layering_ms: f64,
    pub render_ms: f64,
    pub total_ms: f64,
}

/// The stack the last render used, and what it was layered for.
struct Layered {
    coc: CocModel,
    wants: InputKind,
    /// The layering options (spacing, most layers, deep clustering) it was cut with.
    input: InputOptions,
    loaded: LoadedInput,
    /// What the methods keep from one render of `loaded`'s stack for the next ([`StackMemo`]).
    memo: StackMemo,
}

/// A resident renderer over one input (see the module note).
pub struct Session {
    // Declared before the context: dropped first, while the device still exists.
    /// Each method's renderer, on the device or (true) on the CPU.
    renderers: HashMap<(&'static str, bool), Box<dyn Renderer>>,
    input: ReadInput,
    layered: Option<Layered>,
    // Shared: a server keeps one device for every stack it holds.
    context: Option<Arc<Context>>,
}

impl Session {
    /// A session over `input` on `context` (None: the CPU references).
    pub fn new(context: Option<Arc<Context>>, input: ReadInput) -> Self {
        Self { renderers: HashMap::new(), input, layered: None, context }
    }

    pub fn context(&self) -> Option<&Context> {
        self.context.as_deref()
    }

    /// Renders the session's input as `job` says (its input options and camera; the file read
    /// and the header stay the session's), with the overscan cut; returns the image and what
    /// the render did.
    pub fn render(&mut self, job: &RenderJob) -> Result<(Image, SessionRender)> {
        let start = Instant::now();
        let spec = job.spec();
        let method = job.method();
        let wants = method.input();
        let camera = self.input.camera(&spec.camera, &CameraHints::default())?;
        let reusable = self.layered.as_ref().is_some_and(|l| {
            l.wants == wants
                && l.input == spec.input
                && (!self.input.layering_depends_on_camera(wants) || l.coc == camera.lens.coc)
        });
        let mut stats = SessionRender::default();
        if reusable {
            let layered = self.layered.as_mut().expect("checked above");
            layered.loaded.camera = camera;
        } else {
            let layering = Instant::now();
            let coc = camera.lens.coc;
            let loaded = self.input.loaded(&spec.input, camera, wants)?;
            self.layered = Some(Layered { coc, wants, input: spec.input.clone(), loaded, memo: StackMemo::default() });
            stats.relayered = true;
            stats.layering_ms = ms(layering.elapsed());
        }
        let Layered { loaded, memo, .. } = self.layered.as_ref().expect("set above");
        // On a CPU device (lavapipe) a frame the one-shot render takes to the CPU renders there
        // too: the method's own CPU path is faster than the emulated device, and the session's
        // render keeps the one-shot's bytes. A GPU keeps every frame.
        let on_cpu = self.context.as_ref().is_some_and(|c| c.info().is_cpu()) && job.small_frame_on_cpu(Some(loaded.frame_size()))?;
        let key = (method.name(), on_cpu);
        stats.cpu = on_cpu || self.context.is_none();
        if !self.renderers.contains_key(&key) {
            let renderer = method.prepare(if on_cpu { None } else { self.context.as_deref() })?;
            self.renderers.insert(key, renderer);
            stats.prepared = true;
        }
        let renderer = self.renderers[&key].as_ref();
        let rendering = Instant::now();
        let rendered = job.render_resident(renderer, loaded, None, Some(memo))?;
        let image = job.output(&rendered.image, loaded)?.into_owned();
        stats.render_ms = ms(rendering.elapsed());
        stats.total_ms = ms(start.elapsed());
        Ok((image, stats))
    }

    /// Releases the session's pipelines and stack, and the device unless another session shares
    /// it (then its last holder releases it), reporting any validation error it raised.
    pub fn close(mut self) -> Result<()> {
        self.renderers.clear();
        self.layered = None;
        match self.context.take().map(Arc::try_unwrap) {
            Some(Ok(context)) => context.finish(),
            // Another session still holds the device: its last holder releases it.
            Some(Err(_)) | None => Ok(()),
        }
    }
}

fn ms(d: Duration) -> f64 {
    d.as_micros() as f64 / 1e3
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Aperture, CocModel};
    use crate::character::{BlurRemap, Character};
    use crate::input::CameraRequest;
    use crate::job::JobSpec;
    use crate::render::Method;
    use crate::stack::arrays::{stack_from_arrays, ArrayStack};
    use crate::stack::DepthKind;

    /// One flat image (a near square over a far wall), as arrays: what a compositor hands over.
    fn flat_arrays() -> ArrayStack {
        let (w, h) = (24usize, 20usize);
        let mut rgba = Vec::new();
        let mut depth = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let near = (6..14).contains(&x) && (5..13).contains(&y);
                let c = if near { [0.9, 0.4, 0.1, 1.0] } else { [0.1, 0.3, 0.8 + 0.01 * x as f32, 1.0] };
                rgba.extend(c);
                depth.push(if near { 1.0 } else { 6.0 });
            }
        }
        stack_from_arrays(&rgba, &[h, w, 4], &depth, &[h, w], DepthKind::Z).unwrap()
    }

    fn job(k: f32, focus: f32, aperture: &str, near_blur: f32) -> RenderJob {
        let camera = CameraRequest {
            normalised: Some(CocModel::new(k, focus).unwrap()),
            aperture: Aperture::parse(aperture).unwrap(),
            ..CameraRequest::default()
        };
        let character = Character { remap: BlurRemap { near: near_blur, ..BlurRemap::default() }, ..Character::default() };
        RenderJob::new(JobSpec { method: Method::Oracle, camera, character, ..JobSpec::default() }).unwrap()
    }

    /// `job` with the flat image split into one layer at most.
    fn one_layer(job: RenderJob) -> RenderJob {
        let mut spec = job.spec().clone();
        spec.input.auto_layer.max_layers = 1;
        RenderJob::new(spec).unwrap()
    }

    #[test]
    fn a_session_renders_what_one_shot_renders_and_relayers_only_when_the_cut_changes() {
        let mut session = Session::new(None, ReadInput::from_arrays(flat_arrays()));
        let jobs = [
            (job(4.0, 1.0, "disk", 1.0), true),
            (job(4.0, 1.0, "polygon:6", 1.0), false), // the aperture: same cut
            (job(4.0, 1.0, "disk", 2.0), false),      // the character: same cut
            (job(4.0, 1.0 / 6.0, "disk", 1.0), true), // the focus: a new cut
            (job(4.0, 1.0 / 6.0, "disk", 1.0), false),
            // The layering options: a new cut at the same focus.
            (one_layer(job(4.0, 1.0 / 6.0, "disk", 1.0)), true),
        ];
        for (i, (job, relayers)) in jobs.iter().enumerate() {
            let (image, stats) = session.render(job).unwrap();
            assert_eq!(stats.relayered, *relayers, "render {i}");
            assert_eq!(stats.prepared, i == 0, "render {i}: the method is prepared once");
            let loaded = job.load_arrays(flat_arrays()).unwrap();
            let one_shot = job.render(None, &loaded, None).unwrap().image;
            let one_shot = job.output(&one_shot, &loaded).unwrap();
            assert_eq!(image.pixels, one_shot.pixels, "render {i} equals the one-shot render");
        }
        session.close().unwrap();
    }

}
