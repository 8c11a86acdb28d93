//! Output files named after an input's channels (gradients): every channel of the
//! input, written single-part; multi-part inputs get `<part>.<channel>` names.
use std::collections::BTreeMap;

use super::StackInfo;

/// Channel name -> display-window samples, for every channel of an input file.
pub struct FileChannels<'a> {
    info: &'a StackInfo,
    pub values: BTreeMap<String, Vec<f32>>,
}

/// The input channels of one rendered layer, as output names: R, G, B, A, Z.
pub struct LayerChannelNames {
    pub colour: [Option<String>; 4],
    pub depth: Option<String>,
}

impl<'a> FileChannels<'a> {
    /// Every channel of the file, all samples zero.
    pub fn zeroed(info: &'a StackInfo) -> Self {
        let n = info.display_window.width * info.display_window.height;
        let mut values = BTreeMap::new();
        for (p, part) in info.parts.iter().enumerate() {
            for channel in &part.channels {
                values.insert(output_name(info, p, &channel.name), vec![0.0; n]);
            }
        }
        Self { info, values }
    }

    /// Where the rendered layer `layer` came from, or None if it is not from this file.
    pub fn layer(&self, layer: &str) -> Option<LayerChannelNames> {
        let info = self.info.layers.iter().find(|l| l.name == layer)?;
        let ch = &info.channels;
        let name = |c: &Option<String>| c.as_ref().map(|n| output_name(self.info, info.part, n));
        Some(LayerChannelNames { colour: [name(&ch.red), name(&ch.green), name(&ch.blue), name(&ch.alpha)], depth: name(&ch.depth) })
    }

    pub fn set(&mut self, name: &str, values: Vec<f32>) {
        self.values.insert(name.to_string(), values);
    }

    pub fn into_list(self) -> Vec<(String, Vec<f32>)> {
        self.values.into_iter().collect()
    }
}

fn output_name(info: &StackInfo, part: usize, channel: &str) -> String {
    if info.parts.len() <= 1 {
        return channel.to_string();
    }
    // As the reader names multi-part pass-through channels.
    match info.parts[part].name.as_deref() {
        Some(part_name) if channel.starts_with(&format!("{part_name}.")) => channel.to_string(),
        Some(part_name) => format!("{part_name}.{channel}"),
        None => format!("part{part}.{channel}"),
    }
}
