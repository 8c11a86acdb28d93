//! Frame file patterns: `shot.####.exr` (one `#` per digit, zero-padded, the compositing
//! convention of Nuke, Houdini and Blender) and `shot.%04d.exr` (printf's, as ffmpeg and
//! OpenImageIO write it). A frame is padded to the width and never cut: frame 12345 of
//! `####` is `12345`, as every one of those tools does.
use std::fmt;
use std::path::{Path, PathBuf};

/// A path with one or more frame placeholders (each replaced by the same frame number).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FramePattern {
    parts: Vec<Part>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum Part {
    Literal(String),
    /// The frame number, zero-padded to `width` digits (a sign counts, as in printf).
    Frame { width: usize },
}

impl FramePattern {
    /// The pattern in `path`, or None when it names a single file (no `#` run, no `%d` or
    /// `%0Nd`). A path that is not UTF-8 is a single file.
    pub fn parse(path: &Path) -> Option<Self> {
        let text = path.to_str()?;
        let mut parts = Vec::new();
        let mut literal = String::new();
        let mut rest = text;
        while let Some(c) = rest.chars().next() {
            let placeholder = if c == '#' {
                let width = rest.len() - rest.trim_start_matches('#').len();
                Some((width, width))
            } else if c == '%' {
                printf_width(rest)
            } else {
                None
            };
            match placeholder {
                Some((width, consumed)) => {
                    if !literal.is_empty() {
                        parts.push(Part::Literal(std::mem::take(&mut literal)));
                    }
                    parts.push(Part::Frame { width });
                    rest = &rest[consumed..];
                }
                None => {
                    literal.push(c);
                    rest = &rest[c.len_utf8()..];
                }
            }
        }
        if !literal.is_empty() {
            parts.push(Part::Literal(literal));
        }
        parts.iter().any(|p| matches!(p, Part::Frame { .. })).then_some(Self { parts })
    }

    /// The file of `frame`.
    pub fn path(&self, frame: i64) -> PathBuf {
        let text: String = self
            .parts
            .iter()
            .map(|part| match part {
                Part::Literal(text) => text.clone(),
                Part::Frame { width } => format!("{frame:0width$}"),
            })
            .collect();
        PathBuf::from(text)
    }
}

impl fmt::Display for FramePattern {
    /// As written, with `#` runs for the placeholders.
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        for part in &self.parts {
            match part {
                Part::Literal(text) => f.write_str(text)?,
                Part::Frame { width } => f.write_str(&"#".repeat((*width).max(1)))?,
            }
        }
        Ok(())
    }
}

/// `%d` or `%0Nd` at the start of `text`: (width, bytes consumed). Other `%` are literal.
fn printf_width(text: &str) -> Option<(usize, usize)> {
    let spec = text.strip_prefix('%')?;
    let digits = spec.len() - spec.trim_start_matches(|c: char| c.is_ascii_digit()).len();
    if !spec[digits..].starts_with('d') {
        return None;
    }
    let width = match &spec[..digits] {
        "" => 0,
        padded if padded.starts_with('0') => padded.parse().ok()?,
        // `%4d` pads with spaces in printf: no file-naming tool means that.
        _ => return None,
    };
    Some((width, 1 + digits + 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn expand(pattern: &str, frame: i64) -> String {
        FramePattern::parse(Path::new(pattern)).unwrap().path(frame).display().to_string()
    }

    #[test]
    fn hashes_and_printf_pad_the_frame_to_their_width() {
        assert_eq!(expand("shot.####.exr", 7), "shot.0007.exr");
        assert_eq!(expand("shot.####.exr", 1001), "shot.1001.exr");
        assert_eq!(expand("shot.####.exr", 12345), "shot.12345.exr", "never cut");
        assert_eq!(expand("out/defocus.%04d.exr", 42), "out/defocus.0042.exr");
        assert_eq!(expand("f%d.exr", 42), "f42.exr");
        assert_eq!(expand("#.exr", 3), "3.exr");
        assert_eq!(expand("shot_#####.exr", -5), "shot_-0005.exr", "printf's sign");
        assert_eq!(expand("v###/shot.###.exr", 9), "v009/shot.009.exr", "every placeholder");
    }

    #[test]
    fn single_files_and_other_percent_signs_are_no_pattern() {
        assert_eq!(FramePattern::parse(Path::new("shot.exr")), None);
        assert_eq!(FramePattern::parse(Path::new("50%.exr")), None);
        assert_eq!(FramePattern::parse(Path::new("a%4d.exr")), None, "space padding is no file name");
        assert_eq!(expand("100%_%03d.exr", 1), "100%_001.exr");
    }

    #[test]
    fn display_writes_hashes() {
        assert_eq!(FramePattern::parse(Path::new("a.%04d.exr")).unwrap().to_string(), "a.####.exr");
    }
}
