//! Subcommands. Each one lives in its own file, parses its flags, calls the library, reports.
//! This file only lists them; errors get `anyhow` context here and become exit code 1.
use clap::{Parser, Subcommand};

mod camera_args;
mod devices;

const EXAMPLES: &str = "\
Examples:
  lensblur devices                      list Vulkan devices, mark the one in use
  LENSBLUR_DEVICE=1 lensblur devices    pick a device by index or name substring
  LENSBLUR_VALIDATION=1 lensblur ...    any Vulkan validation message becomes an error";

#[derive(Parser)]
#[command(name = "lensblur", version, about = "Physically based, occlusion-aware lens blur on Vulkan compute", after_help = EXAMPLES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the Vulkan devices and the one lensblur would use.
    Devices(devices::Args),
}

pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Devices(args) => devices::run(args),
    };
    // Validation messages raised while contexts were torn down fail the command too.
    let result = result.and_then(|()| Ok(lensblur::vk::validation::check_unreported()?));
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("lensblur: error: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
