//! The `lensblur` command line: thin; every subcommand lives in `src/cli/`.
mod cli;

fn main() -> std::process::ExitCode {
    quiet_on_closed_pipe();
    cli::main()
}

/// Output piped into a reader that stops early (`lensblur info shot.exr | head`) ends the
/// process quietly, as it ends `cat`: Rust starts with SIGPIPE ignored, which turns the next
/// write into a panic in `println!`. Files are written atomically, so an early end leaves
/// none half-written.
#[cfg(unix)]
fn quiet_on_closed_pipe() {
    // SAFETY: sets one signal's disposition to the default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn quiet_on_closed_pipe() {}
