//! `lensblur farm-template [-o FILE]`: the Open Job Description job template of
//! plugins/openjd, carried by the binary so that host plugins (the Blender add-on's "Render
//! on farm") write job bundles for the lensblur they run, without the source tree.
use std::io::Write as _;
use std::path::PathBuf;

use lensblur::atomic_file::write_atomically;

/// The template, as in the repository (one file, no copy to drift).
const TEMPLATE: &str = include_str!("../../plugins/openjd/lensblur-render.yaml");

#[derive(clap::Args)]
#[command(after_help = "\
Examples:
  lensblur farm-template -o bundle/template.yaml && deadline bundle submit bundle -p Input=... -p Output=... -p Frames=1001-1100
  lensblur farm-template > lensblur-render.yaml

Job parameters: Input, Output (frame patterns), Frames (range expression), ChunkSize, CameraFile
(optional), Args (extra render flags); see the book's page docs/book/src/shots.md.")]
pub struct Args {
    /// Write the template here (appears atomically) instead of printing it.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match &args.output {
        Some(path) => write_atomically(path, |w| {
            w.write_all(TEMPLATE.as_bytes()).map_err(lensblur::Error::io(path))
        })?,
        None => print!("{TEMPLATE}"),
    }
    Ok(())
}
