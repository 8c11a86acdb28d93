//! Files that appear whole or not at all: every output (and the pipeline cache) is written to a
//! temporary file beside its target and renamed into place when complete. The temporaries in
//! flight are registered so that an interrupt (Ctrl-C, SIGTERM, SIGHUP) can remove them.
//!
//! One lock orders the writer against the interrupt: the temporary is created and registered
//! under it, and renamed under it after checking that no interrupt has claimed the outputs.
//! [`interrupt`] takes the lock, marks the process interrupted and removes every registered
//! temporary; its caller keeps the lock until the process exits. So an interrupt either comes
//! before a temporary exists (which is then never created), or while it is being written (it is
//! removed; the writer keeps writing into an unlinked file and is never allowed to rename it),
//! or after the rename (the output is complete). The writer gets an open file, never the path,
//! so it cannot recreate a temporary the interrupt removed.
use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

use crate::{Error, Result};

struct State {
    /// Temporary files being written right now.
    temporaries: Vec<PathBuf>,
    /// Files this process renamed into place.
    written: Vec<PathBuf>,
    interrupted: bool,
}

static STATE: Mutex<State> = Mutex::new(State { temporaries: Vec::new(), written: Vec::new(), interrupted: false });

fn state() -> MutexGuard<'static, State> {
    STATE.lock().unwrap_or_else(|e| e.into_inner())
}

/// The outputs claimed by an interrupt; holding it keeps every writer from creating or renaming
/// a file, so a signal handler holds it until it exits.
pub struct Interrupted(MutexGuard<'static, State>);

impl Interrupted {
    /// Files that were complete and in place before the interrupt.
    pub fn written(&self) -> &[PathBuf] {
        &self.0.written
    }
}

/// Marks the process interrupted and removes every temporary output still being written (for
/// a signal handler that is about to exit; keep the returned value alive until then).
pub fn interrupt() -> Interrupted {
    let mut state = state();
    state.interrupted = true;
    for path in std::mem::take(&mut state.temporaries) {
        let _ = std::fs::remove_file(path);
    }
    Interrupted(state)
}

fn interrupted(path: &Path) -> Error {
    Error::input(path, "interrupted; not written")
}

/// Runs `write` on a temporary file in the target's directory and renames it into place, so
/// readers never see a half-written file and failures (and interrupts) leave nothing behind.
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let file_name = path.file_name().ok_or_else(|| Error::input(path, "output path has no file name"))?;
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    // Process id and a counter: concurrent writers (test threads, other processes) never share one.
    let unique = format!("{}.{}", std::process::id(), COUNTER.fetch_add(1, Ordering::Relaxed));
    let tmp = dir.join(format!(".{}.{unique}.tmp", file_name.to_string_lossy()));
    let io = Error::io(path);
    let file = {
        let mut state = state();
        if state.interrupted {
            return Err(interrupted(path));
        }
        let file = File::create(&tmp).map_err(io)?;
        state.temporaries.push(tmp.clone());
        file
    };
    let mut writer = BufWriter::new(file);
    let result = write(&mut writer).and_then(|()| writer.flush().map_err(io));
    drop(writer);
    let committed = {
        let mut state = state();
        state.temporaries.retain(|p| p != &tmp);
        let renamed = if state.interrupted {
            Err(interrupted(path))
        } else {
            result.and_then(|()| std::fs::rename(&tmp, path).map_err(io))
        };
        if renamed.is_ok() {
            state.written.push(path.to_path_buf());
        }
        renamed
    };
    if committed.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    committed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(test: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("lensblur-atomic-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
    }

    #[test]
    fn a_failed_write_leaves_neither_output_nor_temporary() {
        let dir = scratch("failed");
        let out = dir.join("out.bin");
        let result = write_atomically(&out, |w| {
            w.write_all(b"half").map_err(Error::io(&out))?;
            Err(Error::internal("encoder failed"))
        });
        assert!(result.is_err());
        assert!(listing(&dir).is_empty(), "{:?}", listing(&dir));
        write_atomically(&out, |w| w.write_all(b"whole").map_err(Error::io(&out)))
            .unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"whole");
        assert_eq!(listing(&dir), ["out.bin"], "the temporary was renamed, not copied");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    // The interrupt is process-wide and permanent, so this is the one test that takes it; it
    // runs in the child process of `interrupt_mid_write_child` to keep the other tests free.
    #[test]
    fn an_interrupt_mid_write_removes_the_temporary_and_forbids_the_rename() {
        let Some(dir) = std::env::var_os("LENSBLUR_ATOMIC_CHILD_DIR") else {
            let dir = scratch("interrupt");
            let exe = std::env::current_exe().unwrap();
            let child = std::process::Command::new(exe)
                .args([
                    "--exact",
                    "atomic_file::tests::an_interrupt_mid_write_removes_the_temporary_and_forbids_the_rename",
                ])
                .env("LENSBLUR_ATOMIC_CHILD_DIR", &dir)
                .output()
                .unwrap();
            let report =
                format!("{}{}", String::from_utf8_lossy(&child.stdout), String::from_utf8_lossy(&child.stderr));
            assert!(child.status.success() && report.contains("1 passed"), "the child test failed: {report}");
            assert_eq!(listing(&dir), ["before.bin"], "only the output finished before the interrupt is left");
            std::fs::remove_dir_all(&dir).unwrap();
            return;
        };
        let dir = PathBuf::from(dir);
        let before = dir.join("before.bin");
        write_atomically(&before, |w| w.write_all(b"done").map_err(Error::io(&before)))
            .unwrap();
        let out = dir.join("out.bin");
        let mut claimed = None;
        let result = write_atomically(&out, |w| {
            // The writer has its temporary open and registered when the interrupt lands.
            assert_eq!(listing(&dir).len(), 2, "temporary not created");
            let interrupt = interrupt();
            assert_eq!(interrupt.written(), std::slice::from_ref(&before));
            drop(interrupt); // a handler would hold it until exit; released here to let the writer finish
            claimed = Some(());
            w.write_all(b"more bytes after the interrupt").map_err(Error::io(&out))
        });
        assert!(claimed.is_some());
        let message = crate::error::full_message(&result.unwrap_err());
        assert!(message.contains("out.bin") && message.contains("interrupted"), "{message}");
        assert!(write_atomically(&dir.join("later.bin"), |_| Ok(())).is_err(), "no output after an interrupt");
        assert_eq!(listing(&dir), ["before.bin"]);
    }
}
