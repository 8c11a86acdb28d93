//! Subcommands. Each one lives in its own file, parses its flags, calls the library, reports.
//! This file only lists them; errors get `anyhow` context here and become exit code 1.
use clap::{Parser, Subcommand};

mod raytrace;

#[derive(Parser)]
#[command(
    name = "lensblur",
    version,
    about = "Physically based, occlusion-aware lens blur on Vulkan compute",
    after_help = "Examples:\n  lensblur devices\n  lensblur example -o out/"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Ray-trace a built-in scene's ground truth (pinhole, true layers, thin-lens defocus).
    Raytrace(raytrace::Args),
}

pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result: anyhow::Result<()> = match cli.command {
        Command::Raytrace(args) => raytrace::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("lensblur: error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
