//! Subcommands. Each one parses its flags, calls the library, and reports.
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "lensblur", version, about = "Physically based, occlusion-aware lens blur on Vulkan compute")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {}

pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match cli.command {}
}
