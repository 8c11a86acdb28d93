//! Shots: frame sequences rendered by one process. Which frames (OpenJD range expressions),
//! which files (`####` / `%04d` patterns) and which camera each frame has (a camera file
//! beside the per-frame EXR headers). The render loop itself is the CLI's; this module is the
//! policy a host program or the Blender add-on shares with it.
mod camera_file;
mod frames;
mod pattern;

pub use camera_file::CameraFile;
pub use frames::{parse_frames, MAX_FRAMES};
pub use pattern::FramePattern;

use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// The frames of a shot and the files each one reads and writes.
#[derive(Clone, Debug, PartialEq)]
pub struct Shot {
    pub input: FramePattern,
    pub output: FramePattern,
    /// Ascending.
    pub frames: Vec<i64>,
}

/// One frame of a [`Shot`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ShotFrame {
    pub frame: i64,
    pub input: PathBuf,
    pub output: PathBuf,
}

impl Shot {
    /// `input` and `output` must both be frame patterns (`####`, `%04d`); `frames` is a range
    /// expression. `output_flag` names the output in messages (`-o`).
    pub fn new(input: &Path, output: &Path, output_flag: &str, frames: &str) -> Result<Self> {
        let input_pattern = FramePattern::parse(input).ok_or_else(|| {
            Error::input(input, "--frames renders a sequence, but this input has no frame number pattern (shot.####.exr or shot.%04d.exr)")
        })?;
        let output_pattern = FramePattern::parse(output).ok_or_else(|| {
            Error::input(
                output,
                format!("{output_flag} must name every frame's file with a frame number pattern (out.####.exr or out.%04d.exr) when rendering a sequence"),
            )
        })?;
        Ok(Self { input: input_pattern, output: output_pattern, frames: parse_frames(frames)? })
    }

    pub fn files(&self) -> impl Iterator<Item = ShotFrame> + '_ {
        self.frames.iter().map(|&frame| ShotFrame { frame, input: self.input.path(frame), output: self.output.path(frame) })
    }
}
