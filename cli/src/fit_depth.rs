//! `lensblur fit-depth FILE --target DEFOCUSED.exr -o OUT`: depth from defocus. Optimises the
//! depth channel(s) of a stack so its render matches an observed defocused image (Dr.Bokeh
//! paper Sec. 4.3: L1 + edge-aware smoothness + hierarchical SSIM, Adam). OUT is FILE with the
//! depth channels replaced, in FILE's depth convention; everything else (other channels and
//! their sample types, parts, windows, header) is kept as it was.
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context as _};
use indicatif::{ProgressBar, ProgressStyle};
use lensblur::optim::{fit_depth, FitOptions};
use lensblur::render::grad::Slope;
use lensblur::render::Method;
use lensblur::render::InputKind;
use lensblur::render::Lens;
use lensblur::stack::{
    read_rgba, replace_channels, OutputFormat, ChannelReplacement, DepthKind, HeaderEdits, LayerStack, StackInfo,
};
use lensblur::vk::Context;

use super::camera_args::CameraArgs;
use super::input_args::{check_output_paths, input_files, InputArgs};

const EXAMPLES: &str = "\
Examples:
  lensblur fit-depth layers.exr --target photo_dof.exr -o fitted.exr --focal-length 50 --fstop 2 --focus-distance 3
  lensblur fit-depth layers.exr --target t.exr -o fitted.exr --iters 300 --renderer gausspsf --json
  lensblur fit-depth layers.exr --target t.exr -o fitted.exr --fit-focus --fixed-layers 'bg*'

The colour and alpha of FILE's layers are kept; their depth is optimised (starting from FILE's
depth) so that rendering the stack reproduces --target (R,G,B used). OUT is FILE with only the depth
channels changed (where alpha > 0; same sample type, parts, windows and header); --fit-focus also
stamps the fitted focus distance into its 'focus' attribute. --fixed-layers keeps the depth of known
layers, which is what lets --fit-focus find the focus. The loss is L1 +
edge-aware depth smoothness + hierarchical SSIM (windows 5, 11, 21, 31). --renderer gausspsf
uses the occlusion-free Gaussian-PSF baseline (GaussPSF, Gur & Wolf 2019) for comparison;
`lensblur methods` lists every method.";

#[derive(clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Layered EXR whose depth is fitted.
    pub input: PathBuf,
    /// The observed defocused image (EXR, R,G,B), same size as FILE.
    #[arg(long, value_name = "DEFOCUSED.exr")]
    pub target: PathBuf,
    /// Output: FILE with the depth channel(s) replaced.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub input_args: InputArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Adam iterations.
    #[arg(long, default_value_t = 200)]
    pub iters: usize,
    /// Adam learning rate (in units of the stack's mean disparity).
    #[arg(long, default_value_t = 0.1)]
    pub lr: f64,
    /// Also fit the focus distance (only identifiable when some depth is known: hold it with
    /// --fixed-layers). The fitted focus is printed and stamped into OUT's `focus` attribute.
    #[arg(long)]
    pub fit_focus: bool,
    /// Layers (names or globs, comma-separated) whose depth is known and kept as it is.
    #[arg(long, value_name = "NAME,...", value_delimiter = ',')]
    pub fixed_layers: Vec<String>,
    /// Differentiable renderer: a method with a backward pass, run with leaky soft steps
    /// (drbokeh, drbokeh-compat, or gausspsf, the Gaussian-PSF baseline of the Dr.Bokeh paper).
    #[arg(long, default_value = "drbokeh")]
    pub renderer: Method,
    /// Print a JSON report (loss history, time) on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let start = Instant::now();
    let mut inputs = input_files(&args.input, &args.input_args, &args.camera);
    inputs.push(("the --target input file", &args.target));
    // An output on an input is the graver mistake: said first.
    check_output_paths(&[("-o", &args.output)], &inputs)?;
    OutputFormat::for_output(&args.output, "-o", OutputFormat::EXR)?;
    // Refused before any work: a method without a backward pass.
    if !args.renderer.is_differentiable() {
        bail!("{}", args.renderer.differentiable_error());
    }
    args.input_args.require_channel_stack(&args.input, "fit-depth writes the fitted depth")?;
    let loaded = args.input_args.load(&args.input, &args.camera, InputKind::SingleImage)?;
    let Some(info) = &loaded.info else { bail!("{}: fit-depth needs an EXR stack", args.input.display()) };
    let target = read_rgba(&args.target, None, args.input_args.max_pixels).context("--target")?;
    let ctx = Context::from_env().context("opening the Vulkan device")?;
    let renderer = args.renderer.differentiable(&ctx, Slope::Leaky)?;
    let options = FitOptions {
        iterations: args.iters,
        learning_rate: args.lr,
        fit_focus: args.fit_focus,
        fixed_layers: args.fixed_layers.clone(),
        ..FitOptions::default()
    };
    // The fit reports iteration 0 (the starting loss) to `iters` (after the last step): the
    // bar counts steps, 0/N to N/N, and shows an ETA because a fit takes minutes.
    let bar = if args.json { ProgressBar::hidden() } else { ProgressBar::new(args.iters as u64) };
    bar.set_style(
        ProgressStyle::with_template("fitting depth [{bar:40}] iteration {pos}/{len} loss {msg} {elapsed}, ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    // Between the reports of iterations 1 and 2 lies exactly one step (backward + forward);
    // the first report also holds pipeline creation, so it is not timed.
    let mut first_step_start = None;
    let fitted = fit_depth(renderer.as_ref(), &loaded.stack, &loaded.camera.lens, &target, &options, |i, loss| {
        bar.set_position(i as u64);
        bar.set_message(format!("{loss:.5}"));
        match (i, first_step_start) {
            (1, _) => first_step_start = Some(Instant::now()),
            (2, Some(start)) if !args.json => {
                // Said once, in plain text, so it reaches logs and non-terminals too.
                bar.suspend(|| eprintln!("{}", eta_line(args.iters, start.elapsed())));
            }
            _ => {}
        }
    })?;
    bar.finish_and_clear();
    drop(renderer);
    // Teardown validated before the file appears: a validation error leaves no output.
    ctx.finish()?;

    let focus = FittedFocus::new(&fitted.lens, loaded.camera.physical.is_some());
    let replacements = depth_replacements(info, &fitted.stack, loaded.depth_kind);
    let edits = HeaderEdits { focus: focus.distance.filter(|_| args.fit_focus) };
    replace_channels(&args.input, &args.output, &replacements, edits, args.input_args.max_pixels)
        .context("writing -o")?;
    let (first, best) = (fitted.history.first().copied().unwrap_or(f64::NAN), fitted.history.iter().copied().fold(f64::INFINITY, f64::min));
    if args.json {
        let report = serde_json::json!({
            "input": args.input, "target": args.target, "output": args.output, "renderer": args.renderer,
            "iterations": args.iters, "loss_first": first, "loss_best": best, "loss_history": fitted.history,
            "focus_disparity": focus.disparity, "focus_distance": focus.distance, "seconds": start.elapsed().as_secs_f64(),
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("loss {first:.5} -> {best:.5} in {} iterations ({:.1} s); wrote {}", args.iters, start.elapsed().as_secs_f64(), args.output.display());
        if args.fit_focus {
            println!("{}", focus.describe());
        }
    }
    Ok(())
}

/// What is left of a fit of `iterations` steps after two, one step having taken `step`.
fn eta_line(iterations: usize, step: std::time::Duration) -> String {
    let per = step.as_secs_f64();
    let rest = per * iterations.saturating_sub(2) as f64;
    format!(
        "fitting depth: {iterations} iterations at about {per:.1} s each; about {rest:.0} s to go \
         (--iters N sets the count)"
    )
}

/// The focus after fitting, as a disparity and, for a physical camera, as a distance.
struct FittedFocus {
    disparity: f32,
    /// None for the normalised model, or when the fit went beyond infinity (disparity <= 0).
    distance: Option<f32>,
    physical: bool,
}

impl FittedFocus {
    /// A physical camera's focus disparity is 1 / distance (see `CocModel::from_physical`).
    fn new(lens: &Lens, physical: bool) -> Self {
        let disparity = lens.coc.focus_disparity;
        let distance = (physical && disparity > 0.0).then(|| 1.0 / disparity);
        Self { disparity, distance, physical }
    }

    fn describe(&self) -> String {
        match (self.distance, self.physical) {
            (Some(d), _) => format!("fitted focus: distance {d:.6} (scene units), disparity {:.6}; stamped as 'focus'", self.disparity),
            (None, true) => format!(
                "fitted focus: disparity {:.6}, beyond infinity (no physical distance; not stamped)",
                self.disparity
            ),
            (None, false) => format!("fitted focus: disparity {:.6} (normalised model: no distance)", self.disparity),
        }
    }
}

/// The fitted depth of every layer, for its depth channel in the file's convention; pixels
/// whose stored depth the reader did not use (alpha 0) keep it.
fn depth_replacements(info: &StackInfo, fitted: &LayerStack, kind: DepthKind) -> Vec<ChannelReplacement> {
    let mut out = Vec::new();
    for layer in &fitted.layers {
        let Some(read) = info.layers.iter().find(|l| l.name == layer.name) else { continue };
        let Some(channel) = &read.channels.depth else { continue };
        let values = layer
            .disparity
            .iter()
            .zip(&read.depth_weights)
            .map(|(&d, &weight)| (weight > 0.0).then(|| kind.from_disparity(d)))
            .collect();
        out.push(ChannelReplacement { part: read.part, channel: channel.clone(), values });
    }
    out
}
