//! `lensblur completions SHELL` and `lensblur man`: generated from the same clap definitions
//! as `--help`, so they cannot drift from the flags the binary takes.
use std::path::PathBuf;

use anyhow::Context;
use clap::CommandFactory;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur completions bash > ~/.local/share/bash-completion/completions/lensblur\n  \
lensblur completions zsh > ~/.zfunc/_lensblur\n  lensblur completions fish > ~/.config/fish/completions/lensblur.fish")]
pub struct CompletionsArgs {
    /// The shell to write the completion script for (to standard output).
    shell: clap_complete::Shell,
}

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur man --out ~/.local/share/man/man1 && man lensblur\n  lensblur man | man -l -")]
pub struct ManArgs {
    /// Write one page per command (lensblur.1, lensblur-render.1, ...) into DIR instead of
    /// printing the main page to standard output.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

pub fn completions(args: CompletionsArgs) -> anyhow::Result<()> {
    let mut command = super::Cli::command();
    clap_complete::generate(args.shell, &mut command, "lensblur", &mut std::io::stdout());
    Ok(())
}

pub fn man(args: ManArgs) -> anyhow::Result<()> {
    let command = super::Cli::command();
    match args.out {
        Some(dir) => {
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
            clap_mangen::generate_to(command, &dir).with_context(|| format!("writing man pages into {}", dir.display()))?;
            eprintln!("wrote man pages into {}", dir.display());
        }
        None => clap_mangen::Man::new(command).render(&mut std::io::stdout()).context("writing the man page")?,
    }
    Ok(())
}
