//! The one rule for output files: the extension names the format, and a name lensblur cannot
//! honour is refused before any work. Writing EXR bytes into `out.tif` (or PNG bytes into
//! `a.jpg`) would hand the next program a file that lies about what it is.
use std::path::Path;

use crate::{Error, Result};

/// A format lensblur writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// OpenEXR, linear float (`.exr`).
    Exr,
    /// 8-bit sRGB PNG with alpha (`.png`).
    Png,
    /// 8-bit sRGB JPEG, over black (`.jpg`, `.jpeg`).
    Jpeg,
}

impl OutputFormat {
    /// Every format `render -o` writes.
    pub const ALL: &'static [OutputFormat] = &[OutputFormat::Exr, OutputFormat::Png, OutputFormat::Jpeg];
    /// The 8-bit formats (previews).
    pub const LDR: &'static [OutputFormat] = &[OutputFormat::Png, OutputFormat::Jpeg];
    /// Float data only (gradients, fitted stacks).
    pub const EXR: &'static [OutputFormat] = &[OutputFormat::Exr];

    /// The format `path`'s extension names (case-insensitive), if lensblur writes it.
    pub fn from_extension(path: &Path) -> Option<OutputFormat> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "exr" => Some(OutputFormat::Exr),
            "png" => Some(OutputFormat::Png),
            "jpg" | "jpeg" => Some(OutputFormat::Jpeg),
            _ => None,
        }
    }

    /// How the format is named to users.
    pub fn describe(self) -> &'static str {
        match self {
            OutputFormat::Exr => ".exr (linear float)",
            OutputFormat::Png => ".png (8-bit sRGB)",
            OutputFormat::Jpeg => ".jpg/.jpeg (8-bit sRGB)",
        }
    }

    /// The format of output `path` given with `flag`, if it is one of `allowed`; otherwise an
    /// error naming the file, the flag and the formats it takes.
    pub fn for_output(path: &Path, flag: &str, allowed: &[OutputFormat]) -> Result<OutputFormat> {
        let found = Self::from_extension(path);
        if let Some(format) = found.filter(|f| allowed.contains(f)) {
            return Ok(format);
        }
        let what = match path.extension().and_then(|e| e.to_str()) {
            Some(ext) => format!("'.{ext}' is not a format {flag} writes"),
            None => format!("{flag} has no extension"),
        };
        let supported: Vec<&str> = allowed.iter().map(|f| f.describe()).collect();
        Err(Error::input(
            path,
            format!("{what} (the extension picks the format); use {}; nothing was rendered", supported.join(", ")),
        ))
    }
}
