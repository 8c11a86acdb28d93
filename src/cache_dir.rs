//! Where lensblur keeps what it can rebuild (compiled pipelines, ray-traced benchmark truths,
//! benchmark inputs): the user's cache folder, so a command writes the same place from
//! whichever folder it is run, and never into the current one.
use std::path::PathBuf;

/// `$XDG_CACHE_HOME/lensblur`, else `$HOME/.cache/lensblur`; None when neither is set.
pub fn user_cache_dir() -> Option<PathBuf> {
    let nonempty = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty()).map(PathBuf::from);
    nonempty("XDG_CACHE_HOME").or_else(|| nonempty("HOME").map(|home| home.join(".cache"))).map(|d| d.join("lensblur"))
}

/// The cache folder `name` (e.g. `gt-cache`) inside [`user_cache_dir`], or inside the system's
/// temporary folder when the user has none (a service account without `$HOME`).
pub fn cache_subdir(name: &str) -> PathBuf {
    user_cache_dir().unwrap_or_else(|| std::env::temp_dir().join("lensblur")).join(name)
}
