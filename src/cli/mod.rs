//! Subcommands. Each one lives in its own file, parses its flags, calls the library, reports.
//! This file only lists them; errors get `anyhow` context here and become exit code 1.
use clap::{Parser, Subcommand};

mod info;

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
    /// Describe an EXR stack: parts, channels, layers, depth ranges, camera attributes.
    Info(info::InfoArgs),
}

pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result: anyhow::Result<()> = match cli.command {
        Command::Info(args) => info::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("lensblur: error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
