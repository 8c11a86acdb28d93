//! `lensblur bench <suite>`: every benchmark behind one command, a suite per file. The suites
//! measure; they are not tests (a benchmark prints numbers, a test asserts properties).
use std::path::PathBuf;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use lensblur_dev::bench::{contact_sheet, write_png, BenchReport, HEAT_MAX};
use lensblur::raytrace::GroundTruth;

pub mod depth;
pub mod large;
pub mod perf;
pub mod quality;
pub mod sequence;
pub mod single_image;

const EXAMPLES: &str = "\
Examples:
  lensblur bench quality --quick              every method against ray-traced truth
  lensblur bench single-image                 RGB+Z input: drbokeh-auto, vdslr, gather, OpenDefocus
  lensblur bench large --size 3840x2160       the tiler on a 4K frame: time, tiles, memory
  lensblur bench depth --iters 100            depth from defocus: Dr.Bokeh against GaussPSF
  lensblur bench perf --quick                 kernel timings against the baseline kernel
  lensblur bench sequence --sizes 256         one process per shot against one per frame";

#[derive(clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    #[command(subcommand)]
    suite: Suite,
}

#[derive(clap::Subcommand)]
pub enum Suite {
    /// Score every rendering method against ray-traced ground truth (metrics table, JSON, PNG sheet).
    Quality(quality::Args),
    /// The single-image (RGB+Z) table: drbokeh-auto, vdslr and gather beside OpenDefocus,
    /// on ray-traced and (with --cycles) Blender Cycles scenes.
    SingleImage(single_image::Args),
    /// The tiled renderer on a 4K-8K two-layer frame (time, tiles, memory, taps/s).
    Large(large::Args),
    /// Depth from defocus on the benchmark scenes: Dr.Bokeh vs GaussPSF (depth error, PSNR).
    Depth(depth::Args),
    /// Kernel, backward, end-to-end, aperture and Blender timings on fixed cases.
    Perf(perf::Args),
    /// Frames/s of a shot rendered by one process against one process per frame.
    Sequence(sequence::Args),
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.suite {
        Suite::Quality(args) => quality::run(args),
        Suite::SingleImage(args) => single_image::run(args),
        Suite::Large(args) => large::run(args),
        Suite::Depth(args) => depth::run(args),
        Suite::Perf(args) => perf::run(args),
        Suite::Sequence(args) => sequence::run(args),
    }
}

/// The flags of the suites that score renders against a ground truth (quality, single-image).
#[derive(clap::Args)]
pub struct TruthArgs {
    /// Half resolution and a looser ground-truth tolerance: ranks the methods in a few minutes
    /// with a cold cache, seconds with a warm one.
    #[arg(long)]
    pub quick: bool,
    /// Folder caching the ground truths (keyed by scene and sampling options); by default in
    /// the user cache folder ($XDG_CACHE_HOME/lensblur, else ~/.cache/lensblur), whichever
    /// folder the command runs in.
    #[arg(long, value_name = "DIR", default_value_os_t = lensblur::cache_dir::cache_subdir("gt-cache"))]
    pub cache: PathBuf,
    /// Always ray-trace the ground truth; neither read nor write the cache.
    #[arg(long)]
    pub no_cache: bool,
    /// Comma-separated methods to run (default: all the suite's methods).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Comma-separated scenes (default: all; see `lensblur raytrace --list`).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Write the full report (every scene x method, summaries) as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write a labelled contact sheet of all renders and error maps as PNG.
    #[arg(long, value_name = "FILE.png")]
    pub sheet: Option<PathBuf>,
    /// Write every render as float EXR, `DIR/SCENE/METHOD.exr`, beside the scene's
    /// `truth.exr` and `pinhole.exr`, for a closer look than the contact sheet gives.
    #[arg(long, value_name = "DIR")]
    pub renders: Option<PathBuf>,
}

impl TruthArgs {
    /// Refused before minutes of ray tracing, like render's outputs: the sheet is a PNG.
    pub fn check_sheet(&self) -> anyhow::Result<()> {
        if let Some(sheet) = &self.sheet {
            lensblur::stack::OutputFormat::for_output(sheet, "--sheet", &[lensblur::stack::OutputFormat::Png])?;
        }
        Ok(())
    }

    /// The ground-truth cache, unless --no-cache.
    pub fn cache(&self) -> Option<&std::path::Path> {
        (!self.no_cache).then_some(self.cache.as_path())
    }

    /// Writes the report's JSON and contact sheet where asked.
    pub fn write_outputs(&self, truths: &[GroundTruth], report: &BenchReport) -> anyhow::Result<()> {
        if let Some(path) = &self.json {
            let text = serde_json::to_string_pretty(report)?;
            std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
            eprintln!("wrote {}", path.display());
        }
        if let Some(path) = &self.sheet {
            write_png(&contact_sheet(truths, report)?, path)?;
            eprintln!("wrote {} (error scale: 0 to {HEAT_MAX} in display values)", path.display());
        }
        if let Some(dir) = &self.renders {
            write_renders(dir, truths, report)?;
            eprintln!("wrote the renders under {}", dir.display());
        }
        Ok(())
    }
}

/// `DIR/SCENE/{truth,pinhole,METHOD}.exr`, linear float RGBA as the methods returned them.
fn write_renders(dir: &std::path::Path, truths: &[GroundTruth], report: &BenchReport) -> anyhow::Result<()> {
    let options = lensblur::stack::WriteOptions { sample_type: lensblur::stack::SampleType::Float, ..Default::default() };
    for ((scene, renders), truth) in report.scenes.iter().zip(&report.renders).zip(truths) {
        let folder = dir.join(scene);
        std::fs::create_dir_all(&folder).with_context(|| format!("creating {}", folder.display()))?;
        let named = [("truth", &truth.defocused), ("pinhole", &truth.pinhole)].into_iter();
        let methods = report.methods.iter().map(|m| m.name.as_str()).zip(renders);
        for (name, image) in named.chain(methods) {
            lensblur::stack::write_image(&folder.join(format!("{name}.exr")), image, &options)?;
        }
    }
    Ok(())
}

fn bar(prefix: &str, unit: &str) -> anyhow::Result<ProgressBar> {
    let template = format!("{{bar:30}} {{pos}}/{{len}} {unit} [{{elapsed}}] {prefix}");
    let style = ProgressStyle::with_template(&template).context("progress bar template")?;
    Ok(ProgressBar::new(0).with_style(style))
}
