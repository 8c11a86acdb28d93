//! The `lensblur` command line, a thin front end of the library: each subcommand lives in its
//! own file, parses its flags, builds the library's job, runs it and reports. This file only
//! lists them; errors get `anyhow` context here and become exit code 1.
use clap::{Parser, Subcommand};

mod bench;
mod camera_args;
mod character_args;
mod devices;
mod example;
mod farm_template;
mod fit_depth;
mod gpu_kit;
mod grad;
mod info;
mod input_args;
mod memory;
mod method_args;
mod methods;
mod progress;
mod raytrace;
mod render;
mod render_sequence;
mod serve;
mod shell;
mod version;
mod words;

const EXAMPLES: &str = "\
Examples:
  lensblur example -o example-out       ray-trace a built-in scene, render it, compare
  lensblur render shot.exr -o out.exr --focal-length 50 --fstop 2 --focus-distance 3
  lensblur devices                      list Vulkan devices, mark the one in use
  lensblur methods                      the rendering methods and the flags each accepts
  lensblur serve                        a resident renderer: JSON lines on stdin/stdout
  lensblur info shot.exr                every layer and channel of a file, depth ranges
  lensblur completions bash             shell completions (also zsh, fish); `lensblur man` the man page
  lensblur raytrace --list              the built-in ground-truth scenes
  lensblur raytrace fence -o out/fence  ray-trace one scene: pinhole, true layers, defocus
  lensblur bench quality --quick        score every method against ray-traced truth
  LENSBLUR_DEVICE=1 lensblur devices    pick a device by index or name substring
  LENSBLUR_VALIDATION=1 lensblur ...    any Vulkan validation message becomes an error
  LENSBLUR_PIPELINE_CACHE=off lensblur  do not keep compiled pipelines in ~/.cache/lensblur
  LENSBLUR_PROFILE=1 lensblur render .. print the device time of each compute shader on exit
  NO_COLOR=1 lensblur ...               no colour in help, errors or progress bars";

#[derive(Parser)]
#[command(name = "lensblur", version, about = "Physically based, occlusion-aware lens blur on Vulkan compute", after_help = EXAMPLES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a layer stack (EXR, or PNG/JPEG + depth) with lens blur; write EXR or PNG/JPEG.
    Render(Box<render::Args>),
    /// Gradients of a loss w.r.t. every channel of a stack and the camera (backward pass).
    Grad(grad::Args),
    /// Depth from defocus: fit a stack's depth so its render matches a defocused image.
    FitDepth(fit_depth::Args),
    /// Ray-trace a built-in scene, render its layers, compare with the ground truth.
    Example(example::Args),
    /// Print the Open Job Description job template that renders a shot on a render farm.
    FarmTemplate(farm_template::Args),
    /// List the Vulkan devices and the one lensblur would use.
    Devices(devices::Args),
    /// List the rendering methods: what each reads, where it runs, which flags it accepts.
    Methods(methods::Args),
    /// Describe a file: layers, channels, data windows, depth ranges, camera attributes.
    Info(info::InfoArgs),
    /// Ray-trace a built-in scene's ground truth (pinhole, true layers, thin-lens defocus).
    Raytrace(raytrace::Args),
    /// Benchmarks: quality, single-image, large, depth, perf, sequence (`lensblur bench --help`).
    Bench(bench::Args),
    /// The former spellings of `bench large`, `bench depth`, `bench perf`, `bench sequence`.
    #[command(hide = true)]
    BenchLarge(bench::large::Args),
    #[command(hide = true)]
    BenchDepth(bench::depth::Args),
    #[command(hide = true)]
    BenchPerf(bench::perf::Args),
    #[command(hide = true)]
    BenchSequence(bench::sequence::Args),
    /// A resident renderer speaking JSON lines on stdin/stdout: load a stack once, refocus it
    /// many times (hosts such as the Blender add-on's Live mode).
    Serve(serve::Args),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions(shell::CompletionsArgs),
    /// Print the man page, or write one page per command into a folder.
    Man(shell::ManArgs),
    /// Every device pass against its CPU reference, and the sequence path (the GPU kit).
    #[command(hide = true)]
    SelfCheck(gpu_kit::SelfCheckArgs),
    /// Device timings of the GPU kit's fixed cases (256^2 to 8K, forward, backward, multiview, vdslr).
    #[command(hide = true)]
    GpuTimings(gpu_kit::TimingsArgs),
}

fn main() -> std::process::ExitCode {
    quiet_on_closed_pipe();
    memory::keep_freed_memory_for_reuse();
    let cli = version::parse();
    // A one-file render's frame size, read from its header once: the memory advice takes it
    // before any other thread starts (the pool's workers make their heaps as advised), and the
    // render places its work by it.
    let render_frame = match &cli.command {
        Command::Render(args) if args.frames.is_none() => lensblur::input::declared_frame_size(&args.input),
        _ => None,
    };
    memory::advise_huge_pages_for_preview(render_frame);
    // Ctrl-C, SIGTERM, SIGHUP: outputs appear by rename only when complete; remove any
    // temporary being written, and keep every writer from renaming until the process exits.
    let _ = ctrlc::set_handler(|| {
        let interrupted = lensblur::atomic_file::interrupt();
        match interrupted.written() {
            [] => eprintln!("lensblur: interrupted; no output written"),
            done => {
                let done: Vec<String> = done.iter().map(|p| p.display().to_string()).collect();
                eprintln!(
                    "lensblur: interrupted; complete before the interrupt: {}; nothing else written",
                    done.join(", ")
                );
            }
        }
        std::process::exit(130);
    });
    let result = match cli.command {
        // A frame range renders a shot (render_sequence builds on render's steps), else one file.
        Command::Render(args) => match args.frames.clone() {
            Some(frames) => render_sequence::run(&args, &frames),
            None => render::run(*args, render_frame),
        },
        Command::Example(args) => example::run(args),
        Command::Grad(args) => grad::run(args),
        Command::FitDepth(args) => fit_depth::run(args),
        Command::FarmTemplate(args) => farm_template::run(args),
        Command::Devices(args) => devices::run(args),
        Command::Methods(args) => methods::run(args),
        Command::Info(args) => info::run(args),
        Command::Raytrace(args) => raytrace::run(args),
        Command::Bench(args) => bench::run(args),
        Command::BenchLarge(args) => bench::large::run(args),
        Command::BenchDepth(args) => bench::depth::run(args),
        Command::BenchPerf(args) => bench::perf::run(args),
        Command::BenchSequence(args) => bench::sequence::run(args),
        Command::Serve(args) => serve::run(args),
        Command::Completions(args) => shell::completions(args),
        Command::Man(args) => shell::man(args),
        Command::SelfCheck(args) => gpu_kit::self_check(args),
        Command::GpuTimings(args) => gpu_kit::timings(args),
    };
    // Validation messages raised while contexts were torn down fail the command too.
    let result = result.and_then(|()| Ok(lensblur::vk::validation::check_unreported()?));
    if let Some(table) = lensblur::vk::profile::report() {
        eprint!("{table}");
    }
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("lensblur: error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Output piped into a reader that stops early (`lensblur info shot.exr | head`) ends the
/// process quietly, as it ends `cat`: Rust starts with SIGPIPE ignored, which turns the next
/// write into a panic in `println!`. Files are written atomically, so an early end leaves
/// none half-written.
#[cfg(unix)]
fn quiet_on_closed_pipe() {
    // SAFETY: sets one signal's disposition to the default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn quiet_on_closed_pipe() {}
