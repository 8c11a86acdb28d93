//! What a stack file held besides the pixels the renderer needs: where each layer came from,
//! the file's windows and camera attributes, and the channels we do not render.
use std::collections::BTreeMap;
use std::path::PathBuf;

use super::naming::{Convention, LayerChannels};
use super::{DepthKind, LayerStack, StackNaming};

/// A pixel rectangle in EXR coordinates (data or display window).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Window {
    pub x: i32,
    pub y: i32,
    pub width: usize,
    pub height: usize,
}

/// How samples of a channel are stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SampleType {
    #[default]
    Half,
    Float,
    Uint,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ChannelInfo {
    pub name: String,
    pub sample_type: SampleType,
}

/// One part (header) of the file.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PartInfo {
    pub name: Option<String>,
    pub data_window: Window,
    pub compression: String,
    pub channels: Vec<ChannelInfo>,
}

/// Where one rendered layer came from.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LayerInfo {
    pub name: String,
    pub convention: Convention,
    pub part: usize,
    pub channels: LayerChannels,
    pub data_window: Window,
    /// Stored depth values over pixels with alpha > 0 (file units, before conversion).
    pub stored_depth_range: Option<(f32, f32)>,
    /// Disparity after conversion and fill (what the renderer sees).
    pub disparity_range: (f32, f32),
    /// Per display-window pixel, the fill weight of the stored depth sample: 0 where it was
    /// not read and the depth came from the neighbours (see
    /// [`known_depth_weight`](super::depth_clean::known_depth_weight)); empty for layers made by
    /// auto-layering.
    #[serde(skip)]
    pub depth_weights: Vec<f32>,
}

/// A channel the renderer does not touch, resampled onto the display window so it can be
/// written back unchanged (`--keep-channels`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ExtraChannel {
    pub name: String,
    pub sample_type: SampleType,
    #[serde(skip)]
    pub values: Vec<f32>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StackInfo {
    pub path: PathBuf,
    pub display_window: Window,
    pub depth_kind: DepthKind,
    /// One flat RGB+Z image (or a layer named `All`): the caller should auto-layer it.
    pub single_image: bool,
    pub parts: Vec<PartInfo>,
    /// In the order of `StackFile::stack.layers` (front to back).
    pub layers: Vec<LayerInfo>,
    /// Camera-related header attributes (standard ones and stamped metadata), as text.
    pub camera: BTreeMap<String, String>,
    pub extra_channels: Vec<ExtraChannel>,
    /// Things the reader repaired (e.g. NaN/Inf replaced under `replace_nonfinite`).
    pub warnings: Vec<String>,
}

impl StackInfo {
    /// How a result named after a layer is written for this input: in the convention of its
    /// (front) layer, see [`StackNaming::for_convention`].
    pub fn output_naming(&self) -> StackNaming {
        self.layers.first().map_or(StackNaming::default(), |l| StackNaming::for_convention(l.convention))
    }
}

/// A stack as read from a file, with everything needed to write results back.
#[derive(Clone, Debug)]
pub struct StackFile {
    pub stack: LayerStack,
    pub info: StackInfo,
}
