//! `lensblur --version`: the build (version, commit, profile) and the Vulkan device the binary
//! would use with its API level, because a bug report needs both. The device is looked up
//! only when the version is asked for: every other command starts without it.
use clap::{CommandFactory, FromArgMatches, Parser};

use super::Cli;

/// Parses the command line; `--version`/`-V` as the first argument gets the long version.
pub fn parse() -> Cli {
    let asks_version = std::env::args_os().nth(1).is_some_and(|a| a == "--version" || a == "-V");
    if !asks_version {
        return Cli::parse();
    }
    // clap wants a 'static string; the process prints it and exits.
    let text: &'static str = Box::leak(long_version().into_boxed_str());
    let matches = Cli::command().version(text).long_version(text).get_matches();
    Cli::from_arg_matches(&matches).unwrap_or_else(|error| error.exit())
}

fn long_version() -> String {
    let build = format!(
        "{} (commit {}, {} build)",
        env!("CARGO_PKG_VERSION"),
        lensblur::BUILD_COMMIT,
        lensblur::BUILD_PROFILE
    );
    let options = lensblur::vk::ContextOptions::from_env();
    let device = match lensblur::vk::list_devices(&options) {
        Ok((devices, Some(chosen))) => match devices.iter().find(|d| d.index == chosen) {
            Some(d) => format!("Vulkan device: {} [{}], Vulkan API {}, driver {}", d.name, d.kind, d.api_version, d.driver),
            None => "Vulkan device: none chosen".to_string(),
        },
        Ok((_, None)) => "Vulkan device: none matches LENSBLUR_DEVICE (see `lensblur devices`)".to_string(),
        Err(error) => format!("Vulkan device: none ({error})"),
    };
    format!("{build}\n{device}")
}
