//! What users of Rust command-line tools expect (issue 37), through the real binary: shell
//! completions and man pages generated from the same definitions as --help, a --version that
//! names the build and the Vulkan device, NO_COLOR, and every benchmark under `bench <suite>`.
mod common;

use std::process::Command;

fn stdout_of(args: &[&str], env: &[(&str, &str)]) -> String {
    let output = common::lensblur(args, env);
    assert!(output.status.success(), "{args:?} failed: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).expect("utf-8 output")
}

/// The commands `lensblur --help` lists (hidden ones are not listed).
fn listed_commands() -> Vec<String> {
    let help = stdout_of(&["--help"], &[]);
    let section = help.lines().skip_while(|l| *l != "Commands:").skip(1).take_while(|l| l.starts_with("  "));
    section.filter_map(|l| l.split_whitespace().next()).filter(|c| *c != "help").map(str::to_string).collect()
}

#[test]
fn bash_completion_parses_and_offers_every_listed_command() {
    let script = stdout_of(&["completions", "bash"], &[]);
    let dir = common::temp_dir("cli-shell", "bash");
    let file = dir.join("lensblur.bash");
    std::fs::write(&file, &script).unwrap();
    // Source the script, then ask the completion function for `lensblur <TAB>` and
    // `lensblur bench <TAB>` as bash would.
    let probe = format!(
        "source '{}'; complete -p lensblur >/dev/null || exit 3; \
         COMP_WORDS=(lensblur ''); COMP_CWORD=1; _lensblur lensblur '' lensblur; echo \"${{COMPREPLY[*]}}\"; \
         COMP_WORDS=(lensblur bench ''); COMP_CWORD=2; _lensblur lensblur '' bench; echo \"${{COMPREPLY[*]}}\"",
        file.display()
    );
    let output = Command::new("bash").args(["-c", &probe]).output().unwrap();
    assert!(output.status.success(), "sourcing the completion failed: {}", String::from_utf8_lossy(&output.stderr));
    let stdout = String::from_utf8_lossy(&output.stdout);
    let mut lines = stdout.lines();
    let top: Vec<&str> = lines.next().unwrap_or_default().split_whitespace().collect();
    for command in listed_commands() {
        assert!(top.contains(&command.as_str()), "`lensblur <TAB>` lacks {command}: {top:?}");
    }
    // clap_complete's bash generator also offers hidden commands (the old bench-* spellings
    // and the GPU kit's); they run, so completing them is harmless.
    let suites: Vec<&str> = lines.next().unwrap_or_default().split_whitespace().collect();
    for suite in ["quality", "single-image", "large", "depth", "perf", "sequence"] {
        assert!(suites.contains(&suite), "`lensblur bench <TAB>` lacks {suite}: {suites:?}");
    }
}

#[test]
fn zsh_and_fish_completions_name_the_commands() {
    for shell in ["zsh", "fish"] {
        let script = stdout_of(&["completions", shell], &[]);
        for command in ["render", "bench", "single-image", "--focus-distance"] {
            assert!(script.contains(command), "{shell} completion lacks {command}");
        }
    }
}

#[test]
fn man_pages_cover_every_listed_command_and_render_with_groff() {
    let dir = common::temp_dir("cli-shell", "man");
    let output = common::lensblur(&["man", "--out", dir.to_str().unwrap()], &[]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    for command in listed_commands() {
        let page = dir.join(format!("lensblur-{command}.1"));
        assert!(page.exists(), "no man page for {command} in {}", dir.display());
    }
    assert!(dir.join("lensblur-bench-single-image.1").exists(), "no page for a bench suite");
    assert!(!dir.join("lensblur-self-check.1").exists(), "a hidden command got a page");
    // groff -ww warns about malformed requests on stderr; a page must render cleanly.
    let main_page = dir.join("lensblur.1");
    let rendered = Command::new("groff").args(["-man", "-Tutf8", "-ww"]).arg(&main_page).output().unwrap();
    let (text, warnings) = (String::from_utf8_lossy(&rendered.stdout), String::from_utf8_lossy(&rendered.stderr));
    assert!(rendered.status.success() && warnings.trim().is_empty(), "groff: {warnings}");
    assert!(text.contains("occlusion") && text.contains("render"), "{text}");
    // Without --out the main page goes to standard output.
    assert!(stdout_of(&["man"], &[]).contains(".TH lensblur 1"));
}

#[test]
fn version_names_the_build_and_the_vulkan_device() {
    let version = stdout_of(&["--version"], &[]);
    assert!(version.starts_with(&format!("lensblur {} (commit ", env!("CARGO_PKG_VERSION"))), "{version}");
    assert!(version.contains(" build)"), "{version}");
    assert!(version.contains("Vulkan API 1."), "no device API level: {version}");
    // Without a device the version still prints, and says why there is none.
    let version = stdout_of(&["-V"], &common::NO_VULKAN);
    assert!(version.contains("Vulkan device: none"), "{version}");
}

/// `lensblur --help` in a pseudo-terminal (util-linux `script`), so clap decides on colour as
/// it would for a user.
fn help_in_a_terminal(no_color: bool) -> String {
    let bin = env!("CARGO_BIN_EXE_lensblur");
    let mut command = Command::new("script");
    command.args(["-qec", &format!("{bin} --help"), "/dev/null"]).env("TERM", "xterm-256color").env_remove("CLICOLOR_FORCE");
    command.env_remove("NO_COLOR").env_remove("CLICOLOR");
    if no_color {
        command.env("NO_COLOR", "1");
    }
    let output = command.output().expect("util-linux script runs");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8_lossy(&output.stdout).into_owned()
}

#[test]
fn no_color_turns_off_colour_in_a_terminal() {
    assert!(help_in_a_terminal(false).contains("\x1b["), "a terminal gets no colour at all: the check below proves nothing");
    let plain = help_in_a_terminal(true);
    assert!(plain.contains("Usage:") && !plain.contains("\x1b["), "NO_COLOR=1 still coloured: {plain:?}");
}

#[test]
fn every_benchmark_is_a_suite_of_bench_and_old_spellings_still_run() {
    let help = stdout_of(&["bench", "--help"], &[]);
    for suite in ["quality", "single-image", "large", "depth", "perf", "sequence"] {
        assert!(help.lines().any(|l| l.trim_start().starts_with(suite)), "bench --help lacks {suite}: {help}");
    }
    let top = listed_commands();
    assert!(!top.iter().any(|c| c.starts_with("bench-")), "bench-* still listed: {top:?}");
    // Scripts written against the old spellings keep working.
    for old in ["bench-large", "bench-depth", "bench-perf", "bench-sequence"] {
        stdout_of(&[old, "--help"], &[]);
    }
}
