//! Channel naming conventions: turning flat EXR channel names into layers and roles.
//!
//! EXR stores channels sorted by name, so every mapping here is by name, never by index.
//! A name is `[layer.][pass.]channel`; the pass component is stripped only when it is one
//! Blender or Nuke uses for colour (`Combined`, `Image`, `rgba`) or depth (`Depth`, `Z`) and
//! the channel fits it, so `View.Normal.Z` stays a separate (non-rendered) group.
use std::collections::BTreeMap;

/// The naming convention a layer was found in; outputs are written back in the same one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Convention {
    /// `<ViewLayer>.Combined.{R,G,B,A}` + `<ViewLayer>.Depth.Z`.
    BlenderMultilayer,
    /// Blender's File Output node: colour slot + depth slot stored as `<Name>.V`.
    BlenderFileOutput,
    /// OpenEXR / OIIO / Nuke: `layer.R|G|B|A|Z` or long names `layer.red|...|depth`.
    LayerDotChannel,
    /// `R,G,B,A,Z` without prefix: the whole file is one layer.
    Unprefixed,
    /// One layer per part of a multi-part file; the part name is the layer name.
    MultiPart,
}

/// What one channel means to the renderer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Red,
    Green,
    Blue,
    Alpha,
    Depth,
}

/// A channel name split into its layer and role (`role == None`: not rendered).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParsedName {
    pub layer: String,
    pub role: Option<Role>,
    /// The name carried a Blender pass component (`Combined`, `Depth`).
    pub blender_pass: bool,
    /// Depth came from a File Output value channel (`V`).
    pub value_depth: bool,
}

fn role_of(channel: &str) -> Option<Role> {
    match channel.to_ascii_lowercase().as_str() {
        "r" | "red" => Some(Role::Red),
        "g" | "green" => Some(Role::Green),
        "b" | "blue" => Some(Role::Blue),
        "a" | "alpha" => Some(Role::Alpha),
        "z" | "depth" => Some(Role::Depth),
        _ => None,
    }
}

/// Pass (or File Output slot suffix) names that hold colour, lower case.
pub(super) const COLOUR_PASSES: [&str; 4] = ["combined", "image", "rgba", "composite"];
/// Pass (or File Output slot suffix) names that hold depth, lower case.
pub(super) const DEPTH_PASSES: [&str; 2] = ["depth", "z"];

fn is_colour_pass(pass: &str) -> bool {
    COLOUR_PASSES.contains(&pass.to_ascii_lowercase().as_str())
}

fn is_depth_pass(pass: &str) -> bool {
    DEPTH_PASSES.contains(&pass.to_ascii_lowercase().as_str())
}

/// Splits one channel name (see module docs).
pub fn parse_channel(name: &str) -> ParsedName {
    let mut parts: Vec<&str> = name.split('.').collect();
    let channel = parts.pop().unwrap_or_default();
    let pass = parts.last().copied();
    let mut role = role_of(channel);
    let value = channel == "V";
    let mut strip = false;
    if let Some(pass) = pass {
        let colour = matches!(role, Some(Role::Red | Role::Green | Role::Blue | Role::Alpha));
        if is_depth_pass(pass) && (role == Some(Role::Depth) || value) {
            role = Some(Role::Depth);
            strip = true;
        } else if is_colour_pass(pass) && colour {
            strip = true;
        }
    }
    let blender_pass = strip && pass.is_some_and(|p| p == "Combined" || p == "Depth");
    if strip {
        parts.pop();
    }
    ParsedName { layer: parts.join("."), role, blender_pass, value_depth: strip && value }
}

/// The channels of one candidate layer, by full channel name.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct LayerChannels {
    pub red: Option<String>,
    pub green: Option<String>,
    pub blue: Option<String>,
    pub alpha: Option<String>,
    pub depth: Option<String>,
    /// Channels of this group that have no rendering role.
    pub others: Vec<String>,
}

impl LayerChannels {
    /// Colour (R, G, B) and depth are present; alpha may be missing (then opaque).
    pub fn is_complete(&self) -> bool {
        self.red.is_some() && self.green.is_some() && self.blue.is_some() && self.depth.is_some()
    }

    /// Every channel name of the group, for error messages.
    pub fn all_names(&self) -> Vec<String> {
        let roles = [&self.red, &self.green, &self.blue, &self.alpha, &self.depth];
        roles.into_iter().flatten().cloned().chain(self.others.iter().cloned()).collect()
    }

    fn slot(&mut self, role: Role) -> &mut Option<String> {
        match role {
            Role::Red => &mut self.red,
            Role::Green => &mut self.green,
            Role::Blue => &mut self.blue,
            Role::Alpha => &mut self.alpha,
            Role::Depth => &mut self.depth,
        }
    }
}

/// A group of channels sharing a layer name within one part.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelGroup {
    pub layer: String,
    pub channels: LayerChannels,
    pub convention: Convention,
    /// Why this group's depth could not be chosen (several File Output depth slots fit it).
    pub ambiguity: Option<String>,
}

/// Groups the channel names of one part into layers by their prefix, in order of first
/// appearance (the first stage of `file_output_slots::group_channels`, which then pairs the
/// depth slots of Blender's File Output node).
pub(super) fn group_by_prefix(names: &[String]) -> Vec<ChannelGroup> {
    let mut order: Vec<String> = Vec::new();
    let mut groups: BTreeMap<String, (LayerChannels, bool, bool)> = BTreeMap::new();
    for name in names {
        let parsed = parse_channel(name);
        if !groups.contains_key(&parsed.layer) {
            order.push(parsed.layer.clone());
        }
        let (channels, blender, value) = groups.entry(parsed.layer).or_default();
        *blender |= parsed.blender_pass;
        match parsed.role {
            // A true `Z` beats a File Output `V` when both exist.
            Some(role) => {
                let slot = channels.slot(role);
                let replace = slot.is_none() || (role == Role::Depth && *value && !parsed.value_depth);
                if replace {
                    if let Some(old) = slot.replace(name.clone()) {
                        channels.others.push(old);
                    }
                    if role == Role::Depth {
                        *value = parsed.value_depth;
                    }
                } else {
                    channels.others.push(name.clone());
                }
            }
            None => channels.others.push(name.clone()),
        }
    }
    order
        .into_iter()
        .filter_map(|layer| {
            let (channels, blender, value) = groups.remove(&layer)?;
            let convention = if value {
                Convention::BlenderFileOutput
            } else if blender {
                Convention::BlenderMultilayer
            } else if layer.is_empty() {
                Convention::Unprefixed
            } else {
                Convention::LayerDotChannel
            };
            Some(ChannelGroup { layer, channels, convention, ambiguity: None })
        })
        .collect()
}

/// Shell-style match with `*` and `?` (layer selection on the command line).
pub fn glob_match(pattern: &str, text: &str) -> bool {
    let (p, t): (Vec<char>, Vec<char>) = (pattern.chars().collect(), text.chars().collect());
    let (mut pi, mut ti) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while ti < t.len() {
        // `*` is a wildcard even where the name holds a literal `*`: tried first, so matching
        // it as a literal cannot use it up.
        if pi < p.len() && p[pi] == '*' {
            star = Some((pi, ti));
            pi += 1;
        } else if pi < p.len() && (p[pi] == '?' || p[pi] == t[ti]) {
            pi += 1;
            ti += 1;
        } else if let Some((sp, st)) = star {
            pi = sp + 1;
            ti = st + 1;
            star = Some((sp, st + 1));
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn blender_multilayer_passes_are_stripped() {
        let groups = group_by_prefix(&names(&[
            "fg.Combined.A",
            "fg.Combined.B",
            "fg.Combined.G",
            "fg.Combined.R",
            "fg.Depth.Z",
            "fg.Normal.X",
            "fg.Normal.Z",
        ]));
        assert_eq!(groups.len(), 2, "{groups:?}");
        assert_eq!(groups[0].layer, "fg");
        assert_eq!(groups[0].convention, Convention::BlenderMultilayer);
        assert!(groups[0].channels.is_complete());
        assert_eq!(groups[0].channels.depth.as_deref(), Some("fg.Depth.Z"));
        assert_eq!(groups[1].layer, "fg.Normal");
        assert!(!groups[1].channels.is_complete(), "normals must not become a layer");
    }

    #[test]
    fn long_names_and_unprefixed() {
        let groups =
            group_by_prefix(&names(&["bg.red", "bg.green", "bg.blue", "bg.alpha", "bg.depth", "R", "G", "B", "Z"]));
        assert_eq!(groups[0].layer, "bg");
        assert_eq!(groups[0].convention, Convention::LayerDotChannel);
        assert!(groups[0].channels.is_complete());
        assert_eq!(groups[1].layer, "");
        assert_eq!(groups[1].convention, Convention::Unprefixed);
        assert!(groups[1].channels.is_complete() && groups[1].channels.alpha.is_none());
    }

    /// Fuzzing finding (`params` target): a literal `*` in the name matched the pattern's `*`
    /// as a character, so `*` did not match `*ir` and `fg*` did not match `fg*x`.
    #[test]
    fn a_star_stays_a_wildcard_over_a_literal_star_in_the_name() {
        assert!(glob_match("*", "*ir"));
        assert!(glob_match("fg*", "fg*x"));
        assert!(glob_match("*x", "a*x"));
        let odd = "\0\0@\u{fffd}\u{fffd}\0\u{fffd}?\0\0\u{fffd}Cfg*";
        assert!(glob_match(odd, odd), "a name matches itself used as a pattern");
        assert!(!glob_match("fg*", "bg*x"));
    }

    #[test]
    fn globs_match_like_a_shell() {
        assert!(glob_match("fg*", "fg_hair"));
        assert!(glob_match("*.bg", "a.b.bg"));
        assert!(glob_match("l?", "l1"));
        assert!(!glob_match("l?", "l12"));
        assert!(!glob_match("fg", "fg2"));
    }
}
