//! The Python package (python/): `cargo test` runs its pytest suite, so CI covers it. The
//! package lives in its own crate and is built into a virtual environment by `.ci/setup`
//! (`maturin develop --release`); this test fails loudly, naming the fix, when that
//! environment, a package in it or a build as new as its sources is missing: a Python suite
//! that was not run must not look like one that passed.
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::SystemTime;

use lensblur::cache_dir::cache_subdir;

// The repository root: these tests belong to the cli package (cli/Cargo.toml).
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
const FIX: &str = "run `bash .ci/setup` (it builds this checkout's package into the environment \
                   with maturin, and installs numpy, pytest and torch there if missing)";

/// The virtual environment `.ci/setup` makes: LENSBLUR_PYTHON_VENV, else the user cache's
/// lensblur/pyenv, shared by the checkouts on the machine.
fn venv() -> PathBuf {
    std::env::var_os("LENSBLUR_PYTHON_VENV").map(PathBuf::from).unwrap_or_else(|| cache_subdir("pyenv"))
}

/// The newest modification time of the files under `path` (a file or a folder).
fn newest(path: &Path) -> SystemTime {
    let meta = std::fs::metadata(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    if !meta.is_dir() {
        return meta.modified().unwrap();
    }
    let entries = std::fs::read_dir(path).unwrap();
    entries.map(|e| newest(&e.unwrap().path())).max().unwrap_or(SystemTime::UNIX_EPOCH)
}

/// The built extension module (`maturin develop` puts it beside the package's Python files).
fn extension() -> Option<PathBuf> {
    let folder = Path::new(REPO).join("python/lensblur");
    let entries = std::fs::read_dir(&folder).ok()?;
    entries.map(|e| e.unwrap().path()).find(|p| {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        name.starts_with("_lensblur") && name.ends_with(".so")
    })
}

#[test]
fn the_python_packages_tests_pass() {
    let python = venv().join("bin/python");
    assert!(python.exists(), "no Python environment at {}: {FIX}", venv().display());
    let missing = Command::new(&python)
        .args(["-c", "import importlib.util as u; print(' '.join(m for m in ('numpy', 'pytest', 'torch', 'lensblur') if u.find_spec(m) is None))"])
        .output()
        .expect("running the environment's Python");
    let missing = String::from_utf8_lossy(&missing.stdout).trim().to_string();
    assert!(missing.is_empty(), "{} lacks {missing}: {FIX}", venv().display());
    let built = extension().unwrap_or_else(|| panic!("no built extension in python/lensblur: {FIX}"));
    // The environment is shared: the package it imports must be this checkout's.
    let imported =
        Command::new(&python).args(["-c", "import lensblur._lensblur as m; print(m.__file__)"]).output().unwrap();
    let imported = PathBuf::from(String::from_utf8_lossy(&imported.stdout).trim());
    assert!(
        imported.canonicalize().ok() == built.canonicalize().ok(),
        "{} imports lensblur from {} rather than {}: {FIX}",
        venv().display(),
        imported.display(),
        built.display()
    );
    let built_at = std::fs::metadata(&built).unwrap().modified().unwrap();
    let sources = ["src", "glsl", "build.rs", "Cargo.toml", "python/src", "python/Cargo.toml"];
    for source in sources {
        let path = Path::new(REPO).join(source);
        assert!(newest(&path) <= built_at, "{} is older than {}: {FIX}", built.display(), path.display());
    }
    let status = Command::new(&python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "python/tests"])
        .current_dir(REPO)
        .env("LENSBLUR_BIN", env!("CARGO_BIN_EXE_lensblur"))
        .env("LENSBLUR_VALIDATION", "1")
        .env_remove("LENSBLUR_DEVICE")
        .status()
        .expect("running pytest");
    assert!(status.success(), "the Python package's tests failed (pytest output above)");
}
