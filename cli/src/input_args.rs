//! Input flags shared by `render`, `grad` and `fit-depth`: which file, which layers, how
//! depth is encoded, and how a single image is split into layers; they make the library's
//! [`InputOptions`] and [`lensblur::input::load`] does the rest.
use std::path::{Path, PathBuf};

use anyhow::bail;
use lensblur::camera::CameraHints;
pub use lensblur::input::LoadedInput;
use lensblur::input::{load, InputOptions};
use lensblur::InputMismatch;
use lensblur::render::InputKind;
use lensblur::stack::deep::{DeepReadOptions, PartChoice, DEFAULT_MAX_SAMPLES};
use lensblur::stack::{AutoLayerOptions, DepthKind, DEFAULT_MAX_PIXELS};

use super::camera_args::{flag_error, CameraArgs};

#[derive(clap::Args, Clone, Debug)]
pub struct InputArgs {
    /// Layers to use, by name or glob (`fg*`), comma-separated, any order (they are sorted
    /// front to back by depth). Default: every layer with colour, alpha and depth.
    #[arg(
        long,
        value_name = "NAME,...",
        value_delimiter = ',',
        help_heading = "Input"
    )]
    pub layers: Option<Vec<String>>,
    /// How depth is stored: z (planar, 1e10/inf = far), disparity (normalised, 1 = near) or
    /// inverse-z (1/z, 0 = far). [default: z for EXR, disparity for a --depth image]
    #[arg(long, value_name = "KIND", help_heading = "Input")]
    pub depth_kind: Option<DepthKind>,
    /// Depth image (PNG, 8/16-bit grey) for a PNG/JPEG input; values in [0, 1] per --depth-kind.
    #[arg(long, value_name = "FILE", help_heading = "Input")]
    pub depth: Option<PathBuf>,
    /// Auto-layering of a single image: CoC spacing between layers, in pixels (Lee et al. 2009).
    #[arg(long, value_name = "PX", help_heading = "Input")]
    pub layer_spacing: Option<f32>,
    /// Auto-layering of a single image: most layers to cut it into.
    #[arg(long, value_name = "N", help_heading = "Input")]
    pub max_layers: Option<usize>,
    /// Auto-layering of a single image: render the frame alone, without the canvas guessed
    /// beyond its edge (then a blur at the edge averages only the part of its disk inside the
    /// frame: a light near the edge counts up to twice there).
    #[arg(long, help_heading = "Input")]
    pub no_edge_guess: bool,
    /// Refuse inputs (EXR, PNG/JPEG and --depth images) whose header declares more pixels
    /// than this, before reading pixels.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_PIXELS, help_heading = "Input")]
    pub max_pixels: u64,
    /// Set NaN/Inf colour and alpha samples to 0 (with a warning) instead of refusing the file.
    #[arg(long, help_heading = "Input")]
    pub replace_nonfinite: bool,
    /// Deep EXR files merged with the (deep) input as Nuke's DeepMerge does: every pixel holds
    /// the samples of all of them, and the merge is defocused as one scene.
    #[arg(long, value_name = "FILE,...", value_delimiter = ',', help_heading = "Deep input")]
    pub merge: Vec<PathBuf>,
    /// Refuse deep inputs holding more samples than this (all merged files together), before
    /// decoding the chunk that passes it.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_SAMPLES, help_heading = "Deep input")]
    pub max_samples: u64,
    /// Which part of a multi-part deep file (a stereo file has one per view): its name, its
    /// index, `first` (the first deep part) or `all` (every deep part, merged).
    #[arg(long, value_name = "PART", default_value = "first", help_heading = "Deep input")]
    pub deep_part: PartChoice,
    /// Flatten deep input first (DeepToImage: colour over, the depth of the nearest surface)
    /// and defocus it as one image, auto-layered: what a flat-only defocus makes of it.
    #[arg(long, help_heading = "Deep input")]
    pub deep_flatten: bool,
}

impl InputArgs {
    /// Reads `path`, resolves the camera and, when `input` wants layers and the file holds
    /// one image, splits it into layers (`grad`, `fit-depth`; `render` loads through its job).
    /// The policy is the library's ([`lensblur::input::load`]); this rewords its refusals with
    /// the flags (`--depth`, `--layers`, camera flags) and prints the warnings.
    pub fn load(&self, path: &Path, camera: &CameraArgs, input: InputKind) -> anyhow::Result<LoadedInput> {
        let request = camera.request()?;
        // The library's errors name the file already: no "reading FILE" context on top.
        let loaded = load(path, &self.options(), &request, &CameraHints::default(), input).map_err(input_flag_error)?;
        Ok(warn(loaded))
    }

    /// Refuses an input that `writer` cannot write back into channel by channel (deep,
    /// PNG/JPEG), before reading it ([`lensblur::input::require_channel_stack`]).
    pub fn require_channel_stack(&self, path: &Path, writer: &str) -> anyhow::Result<()> {
        Ok(lensblur::input::require_channel_stack(path, &self.options(), writer)?)
    }

    /// Files these flags read besides the input itself, described for [`check_output_paths`].
    pub fn files(&self) -> Vec<(&'static str, &Path)> {
        let depth = self.depth.iter().map(|p| ("the --depth input file", p.as_path()));
        depth.chain(self.merge.iter().map(|p| ("a --merge input file", p.as_path()))).collect()
    }

    pub fn options(&self) -> InputOptions {
        InputOptions {
            layers: self.layers.clone(),
            depth_kind: self.depth_kind,
            depth_image: self.depth.clone(),
            max_pixels: self.max_pixels,
            replace_nonfinite: self.replace_nonfinite,
            auto_layer: AutoLayerOptions::chosen(self.layer_spacing, self.max_layers, self.no_edge_guess),
            merge: self.merge.clone(),
            deep: DeepReadOptions { max_samples: self.max_samples, max_pixels: self.max_pixels, part: self.deep_part.clone() },
            deep_layers: Default::default(),
            deep_flatten: self.deep_flatten,
        }
    }
}

/// Prints a loaded input's warnings (replaced samples, ignored channels, a depth encoding that
/// cannot drive a physical camera) and hands it on.
pub fn warn(loaded: LoadedInput) -> LoadedInput {
    for warning in &loaded.warnings {
        eprintln!("lensblur: warning: {warning}");
    }
    loaded
}

/// [`flag_error`], plus the input options that do not fit the file's kind, reworded with the
/// flags that set them.
pub fn input_flag_error(error: lensblur::Error) -> anyhow::Error {
    let lensblur::Error::InputMismatch { path, mismatch } = error else {
        return flag_error(error);
    };
    let path = path.display();
    match mismatch {
        InputMismatch::MissingDepthImage => anyhow::anyhow!("{path}: a PNG/JPEG input needs its depth image: --depth DEPTH.png"),
        InputMismatch::LayersOfSingleImage => anyhow::anyhow!("--layers selects layers of an EXR; {path} is a single image"),
        InputMismatch::DepthImageBesideStack => anyhow::anyhow!("--depth is for PNG/JPEG inputs; {path} carries its depth in its channels"),
    }
}

/// Refuses, before any work: an output whose directory does not exist, an output that is one
/// of the inputs (compositors call us with generated paths, and a typo that points an output
/// at a source would destroy it), and two outputs on one path (the second would replace the
/// first). Outputs are named by their flag (`-o`), inputs by what they are ("the input file",
/// "the --depth input file"), so the message says which two collide.
pub fn check_output_paths(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> anyhow::Result<()> {
    for &(flag, output) in outputs {
        let dir = output.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !dir.is_dir() {
            bail!("{flag} {}: output directory {} does not exist; create it first (nothing was rendered)", output.display(), dir.display());
        }
    }
    check_output_collisions(outputs, inputs)
}

/// The collision part of [`check_output_paths`], for outputs in a folder the command creates
/// (`--debug-out`): none may be an input or another output.
pub fn check_output_collisions(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> anyhow::Result<()> {
    for (i, &(flag, output)) in outputs.iter().enumerate() {
        if let Some((input, _)) = inputs.iter().find(|(_, input)| same_file(output, input)) {
            bail!("{flag} {} is {input}; choose another {flag} path (nothing was written)", output.display());
        }
        if let Some((other, _)) = outputs[..i].iter().find(|(_, other)| same_file(output, other)) {
            bail!("{flag} {} is the same file as {other}; give each output its own path (nothing was written)", output.display());
        }
    }
    Ok(())
}

/// Every file a command reads through the shared flags: the input itself, `--depth`, and an
/// `--aperture image:FILE` kernel, described for [`check_output_paths`].
pub fn input_files<'a>(input: &'a Path, input_args: &'a InputArgs, camera: &'a CameraArgs) -> Vec<(&'static str, &'a Path)> {
    let mut files = vec![("the input file", input)];
    files.extend(input_args.files());
    files.extend(camera.files());
    files
}

/// Whether two paths name one file: the same inode when both exist (symlinks, hard links,
/// `./a` vs `a`), else the same canonical directory and file name (a file not written yet).
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
        use std::os::unix::fs::MetadataExt;
        return (ma.dev(), ma.ino()) == (mb.dev(), mb.ino());
    }
    let resolved = |p: &Path| {
        std::fs::canonicalize(p).ok().or_else(|| {
            let dir = p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
            Some(std::fs::canonicalize(dir).ok()?.join(p.file_name()?))
        })
    };
    match (resolved(a), resolved(b)) {
        (Some(a), Some(b)) => a == b,
        _ => a == b,
    }
}
