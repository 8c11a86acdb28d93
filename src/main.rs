//! The `lensblur` command line: thin; every subcommand lives in `src/cli/`.
mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
