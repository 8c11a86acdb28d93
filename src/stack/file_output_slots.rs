//! Pairing the slots of Blender's File Output node. In a multilayer file it names channels
//! after its slots: a colour slot `fg` gives `fg.R,G,B,A`, a value slot `fgDepth` gives
//! `fgDepth.V`. A stack written by one node thus has colour and depth in separate groups,
//! which are paired here by name: a depth slot is a colour slot's name plus `Depth` or `Z`
//! (any case), with or without a separator (`fg_Depth`, `fgDepth`, `fg-z`), and the colour
//! slot may carry a colour suffix of its own (`fg_Image`, `fgImage`). (`fg.Depth.V` already
//! groups with `fg.R` by its dot, see [`super::naming`].)
use std::collections::BTreeMap;

use super::naming::{group_by_prefix, ChannelGroup, Convention, COLOUR_PASSES, DEPTH_PASSES};

/// Groups the channel names of one part into layers, in order of first appearance: by prefix
/// ([`super::naming`]), then depth slots of Blender's File Output node join the colour slot
/// they are named after.
pub fn group_channels(names: &[String]) -> Vec<ChannelGroup> {
    pair_depth_slots(group_by_prefix(names))
}

const SEPARATORS: [char; 4] = ['_', '.', '-', ' '];

/// `name` without one of `suffixes` (any case) and the separators before it; None when the
/// name has none of them or nothing would remain.
fn strip_suffix<'a>(name: &'a str, suffixes: &[&str]) -> Option<&'a str> {
    suffixes.iter().find_map(|suffix| {
        let cut = name.len().checked_sub(suffix.len())?;
        let (base, tail) = (name.get(..cut)?, name.get(cut..)?);
        let base = base.trim_end_matches(SEPARATORS);
        (tail.eq_ignore_ascii_case(suffix) && !base.is_empty()).then_some(base)
    })
}

/// The one channel of a group that holds nothing but depth (`fgDepth.V`, `fg_z.Z`), and
/// whether it is a File Output value channel.
fn lone_depth_channel(group: &ChannelGroup) -> Option<(String, bool)> {
    let ch = &group.channels;
    if ch.red.is_some() || ch.green.is_some() || ch.blue.is_some() || ch.alpha.is_some() {
        return None;
    }
    match (&ch.depth, ch.others.as_slice()) {
        (Some(depth), []) => Some((depth.clone(), false)),
        (None, [value]) if value.ends_with(".V") => Some((value.clone(), true)),
        _ => None,
    }
}

/// A group with colour but no depth of its own.
fn is_colour_slot(group: &ChannelGroup) -> bool {
    let ch = &group.channels;
    ch.red.is_some() && ch.green.is_some() && ch.blue.is_some() && ch.depth.is_none()
}

/// The names a depth slot may extend to name this colour slot: its own, and without its
/// colour suffix (`fg_Image` -> `fg`).
fn colour_slot_fits(colour: &ChannelGroup, depth_base: &str) -> bool {
    colour.layer == depth_base || strip_suffix(&colour.layer, &COLOUR_PASSES) == Some(depth_base)
}

/// A depth-only group and the colour groups its name fits.
struct DepthSlot {
    group: usize,
    channel: String,
    value: bool,
    colours: Vec<usize>,
}

fn quoted(names: impl IntoIterator<Item = impl AsRef<str>>) -> String {
    names.into_iter().map(|n| format!("'{}'", n.as_ref())).collect::<Vec<_>>().join(", ")
}

/// Moves each depth-only group into the colour group it names (see module docs). Where the
/// pairing is ambiguous nothing is moved and the colour groups concerned say why in
/// [`ChannelGroup::ambiguity`].
pub fn pair_depth_slots(mut groups: Vec<ChannelGroup>) -> Vec<ChannelGroup> {
    let mut slots = Vec::new();
    for (index, group) in groups.iter().enumerate() {
        let Some((channel, value)) = lone_depth_channel(group) else { continue };
        let Some(base) = strip_suffix(&group.layer, &DEPTH_PASSES) else { continue };
        let colours: Vec<usize> =
            (0..groups.len()).filter(|&c| is_colour_slot(&groups[c]) && colour_slot_fits(&groups[c], base)).collect();
        if !colours.is_empty() {
            slots.push(DepthSlot { group: index, channel, value, colours });
        }
    }
    let mut fitting: BTreeMap<usize, Vec<&DepthSlot>> = BTreeMap::new();
    for slot in &slots {
        for &colour in &slot.colours {
            fitting.entry(colour).or_default().push(slot);
        }
    }
    let mut merged = vec![false; groups.len()];
    for (colour, candidates) in fitting {
        let name = |i: usize| groups[i].layer.clone();
        let ambiguity = match candidates.as_slice() {
            [slot] if slot.colours.len() == 1 => None,
            [slot] => Some(format!(
                "File Output depth slot '{}' fits several colour slots ({})",
                name(slot.group),
                quoted(slot.colours.iter().map(|&c| name(c)))
            )),
            several => Some(format!(
                "File Output depth slots {} all fit colour slot '{}'",
                quoted(several.iter().map(|s| name(s.group))),
                name(colour)
            )),
        };
        match (ambiguity, candidates.first()) {
            (Some(message), _) => {
                groups[colour].ambiguity = Some(format!(
                    "{message}; rename the slots so that each colour slot NAME has exactly one depth slot \
                     NAME_Depth"
                ));
            }
            (None, Some(slot)) => {
                groups[colour].channels.depth = Some(slot.channel.clone());
                if slot.value {
                    groups[colour].convention = Convention::BlenderFileOutput;
                }
                merged[slot.group] = true;
            }
            (None, None) => {}
        }
    }
    groups.into_iter().zip(merged).filter(|(_, merged)| !merged).map(|(group, _)| group).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_output_value_depth_pairs_with_image_slot() {
        let groups = groups(&["Depth.V", "Image.A", "Image.B", "Image.G", "Image.R"]);
        assert_eq!(groups.len(), 1);
        assert_eq!(groups[0].convention, Convention::BlenderFileOutput);
        assert_eq!(groups[0].channels.depth.as_deref(), Some("Depth.V"));
        assert_eq!(groups[0].channels.red.as_deref(), Some("Image.R"));
    }

    fn groups(names: &[&str]) -> Vec<ChannelGroup> {
        group_channels(&names.iter().map(|s| s.to_string()).collect::<Vec<_>>())
    }

    fn rgba(slot: &str) -> Vec<String> {
        ["R", "G", "B", "A"].iter().map(|c| format!("{slot}.{c}")).collect()
    }

    #[test]
    fn every_depth_slot_spelling_pairs_with_its_colour_slot() {
        for (colour, depth) in [
            ("fg", "fg_Depth.V"),
            ("fg", "fgDepth.V"),
            ("fg", "fg.Depth.V"),
            ("fg", "fg_Z.V"),
            ("fg", "FG_depth.V"),
            ("fg", "fg-z.V"),
            ("fg_Image", "fg_Depth.V"),
            ("fgImage", "fgDepth.V"),
            ("fg_Image", "fg_Image_Depth.V"),
            ("fg", "fg_depth.Z"),
        ] {
            // Case-insensitive only in the suffix: `FG_depth` names slot `FG`, not `fg`.
            let expected = !depth.starts_with("FG");
            let mut names = rgba(colour);
            names.extend(rgba("bg"));
            names.extend(["bg_Depth.V".to_string(), depth.to_string()]);
            let found = group_channels(&names);
            let fg = found.iter().find(|g| g.layer == colour).unwrap();
            assert_eq!(fg.channels.is_complete(), expected, "{colour} + {depth}: {found:?}");
            if expected {
                assert_eq!(fg.channels.depth.as_deref(), Some(depth), "{colour} + {depth}");
                assert_eq!(found.len(), 2, "the depth slots are absorbed: {found:?}");
            }
            let bg = found.iter().find(|g| g.layer == "bg").unwrap();
            assert_eq!(bg.channels.depth.as_deref(), Some("bg_Depth.V"));
            assert_eq!(bg.convention, Convention::BlenderFileOutput);
        }
    }

    #[test]
    fn ambiguous_depth_slots_pair_nothing_and_say_why() {
        let mut two_depths = rgba("fg");
        two_depths.extend(["fg_Depth.V".to_string(), "fgZ.V".to_string()]);
        let found = group_channels(&two_depths);
        let fg = found.iter().find(|g| g.layer == "fg").unwrap();
        assert!(fg.channels.depth.is_none());
        let message = fg.ambiguity.as_deref().unwrap();
        assert!(message.contains("'fg_Depth'") && message.contains("'fgZ'"), "{message}");

        let mut two_colours = rgba("fg");
        two_colours.extend(rgba("fg_Image"));
        two_colours.push("fg_Depth.V".to_string());
        let found = group_channels(&two_colours);
        for name in ["fg", "fg_Image"] {
            let group = found.iter().find(|g| g.layer == name).unwrap();
            let message = group.ambiguity.as_deref().unwrap_or_default();
            assert!(message.contains("'fg_Depth'") && message.contains("several colour slots"), "{found:?}");
        }
    }

    #[test]
    fn other_passes_and_unrelated_names_are_left_alone() {
        let mut names = rgba("fg");
        // A vector slot and a value slot that names no colour slot stay separate groups.
        names.extend(["fg_Normal.X", "fg_Normal.Y", "fg_Normal.Z", "mist.V", "Blitz.V"].map(String::from));
        let found = groups(&names.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(found.iter().all(|g| !g.channels.is_complete() && g.ambiguity.is_none()), "{found:?}");
        assert_eq!(found.len(), 4);
        assert_eq!(strip_suffix("Depth", &DEPTH_PASSES), None, "a bare suffix names no slot");
    }
}
