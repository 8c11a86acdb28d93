//! The README and the book (`docs/book/`) are what a new user follows from a fresh clone
//! (issues 27, 37): every `lensblur` command they show must run as written. Commands on the
//! example's `example-out/` (and any other quick one) are run, README first, then the book's
//! pages in SUMMARY.md order, in a scratch folder with `lensblur` on PATH as `cargo install
//! --path .` puts it; those that take minutes (benchmarks) or name a placeholder (`SCENE`,
//! `DIR`) are checked for a valid subcommand and flags by running them with `--help` appended
//! (clap rejects an unknown flag before it reaches `--help`). Also: the install step comes
//! before the first command, every relative link resolves, SUMMARY.md lists every page, the
//! book builds with mdBook, the files the commands leave in a checkout are ignored, and the
//! method table covers every method.
mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lensblur::render::Method;

const README: &str = include_str!("../README.md");
// The repository root: these tests belong to the cli package (cli/Cargo.toml).
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

/// One command as a user would type it, with the document and line it starts on.
#[derive(Debug)]
struct ReadmeCommand {
    line: String,
    text: String,
}

/// The book's folder of pages.
fn book_src() -> PathBuf {
    Path::new(REPO).join("docs/book/src")
}

/// The pages SUMMARY.md links, in its order.
fn book_pages() -> Vec<PathBuf> {
    let summary = std::fs::read_to_string(book_src().join("SUMMARY.md")).expect("docs/book/src/SUMMARY.md");
    markdown_links(&summary).into_iter().map(|l| book_src().join(l)).collect()
}

/// The README, then the book's pages in reading order: (name, text).
fn documents() -> Vec<(String, String)> {
    let mut docs = vec![("README.md".to_string(), README.to_string())];
    for page in book_pages() {
        let text = std::fs::read_to_string(&page).unwrap_or_else(|e| panic!("{}: {e}", page.display()));
        docs.push((page.strip_prefix(REPO).unwrap().display().to_string(), text));
    }
    docs
}

/// The targets of `[text](target)` links in a Markdown text.
fn markdown_links(text: &str) -> Vec<&str> {
    text.split("](").skip(1).filter_map(|rest| rest.split(')').next()).collect()
}

/// The lines of a document's code: indented blocks, and fenced blocks marked bash, sh,
/// shell or console (a `$ ` prompt is dropped). Other lines read as empty, so line numbers stay.
fn code_lines(text: &str) -> Vec<Option<String>> {
    let mut fence: Option<bool> = None;
    text.lines()
        .map(|line| {
            let trimmed = line.trim_start();
            if let Some(info) = trimmed.strip_prefix("```") {
                fence = match fence {
                    Some(_) => None,
                    None => Some(matches!(info.trim(), "bash" | "sh" | "shell" | "console")),
                };
                return None;
            }
            match fence {
                Some(true) => Some(format!("    {}", line.strip_prefix("$ ").unwrap_or(line))),
                Some(false) => None,
                None => line.starts_with("    ").then(|| line.to_string()),
            }
        })
        .collect()
}

/// The commands in the documents' code that start with `lensblur` or run it through `cargo run
/// --release -p lensblur-cli --` (the set-up, which is `lensblur` once built). A trailing `\` joins the next
/// line; two or more spaces end the command (the tour's descriptions follow them on the same
/// line).
fn readme_commands() -> Vec<ReadmeCommand> {
    let mut commands = Vec::new();
    for (name, text) in documents() {
        commands.extend(document_commands(&name, &text));
    }
    commands
}

fn document_commands(name: &str, text: &str) -> Vec<ReadmeCommand> {
    let lines: Vec<String> = code_lines(text).into_iter().map(|l| l.unwrap_or_default()).collect();
    let command_part = |line: &str| line.trim().split("  ").next().unwrap_or("").trim().to_string();
    let mut commands = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let line = &lines[i];
        let start = i;
        i += 1;
        let Some(code) = line.strip_prefix("    ") else { continue };
        let mut text = command_part(code);
        if let Some((_, args)) = text.split_once("cargo run --release -p lensblur-cli -- ") {
            text = format!("lensblur {args}");
        }
        if !text.starts_with("lensblur ") {
            continue;
        }
        while let Some(head) = text.strip_suffix('\\') {
            text = format!("{} {}", head.trim_end(), command_part(&lines[i]));
            i += 1;
        }
        commands.push(ReadmeCommand { line: format!("{name}:{}", start + 1), text });
    }
    commands
}

/// Whether running a command fully would take minutes or needs a file the README leaves to
/// the reader (an upper-case placeholder such as `SCENE` or `DIR`).
fn check_flags_only(command: &str) -> bool {
    let words: Vec<&str> = command.split_whitespace().collect();
    let slow = words.get(1) == Some(&"bench");
    let placeholder = words.iter().any(|w| w.len() > 1 && w.chars().all(|c| c.is_ascii_uppercase()));
    slow || placeholder
}

/// Runs `command` with bash in `dir`, `lensblur` on PATH, validation on.
fn shell(dir: &Path, command: &str) -> Output {
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_lensblur")).parent().unwrap();
    let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default());
    Command::new("bash")
        .args(["-c", command])
        .current_dir(dir)
        .env("PATH", path)
        .env("LENSBLUR_VALIDATION", "1")
        .env_remove("LENSBLUR_DEVICE")
        .output()
        .unwrap()
}

fn succeeded(command: &ReadmeCommand, what: &str, output: &Output) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{}: `{what}` failed:\n{stderr}", command.line);
    String::from_utf8_lossy(&output.stdout).into_owned()
}

#[test]
fn every_readme_command_runs_as_written() {
    let dir = common::temp_dir("readme", "commands");
    let commands = readme_commands();
    assert_eq!(
        commands.first().map(|c| c.text.as_str()),
        Some("lensblur example -o example-out"),
        "the quick start comes first and makes example-out/"
    );
    let (mut ran, mut checked) = (Vec::new(), Vec::new());
    for command in &commands {
        assert!(!command.text.contains(['[', '<']), "{}: placeholder syntax in `{}`", command.line, command.text);
        if check_flags_only(&command.text) {
            succeeded(command, &command.text, &shell(&dir, &format!("{} --help", command.text)));
            checked.push(command.text.clone());
            continue;
        }
        let stdout = succeeded(command, &command.text, &shell(&dir, &command.text));
        // The example ends with the same render as a command line: it must run as printed.
        if let Some((_, printed)) = stdout.split_once("same render from the command line: ") {
            let printed = printed.lines().next().unwrap_or_default();
            succeeded(command, printed, &shell(&dir, printed));
        }
        ran.push(command.text.clone());
    }
    // Guards against the extraction silently finding nothing: the tour's commands on the
    // example (render, grad, fit-depth, info, the lens-character render) all ran.
    let on_example = ran.iter().filter(|c| c.contains("example-out/")).count();
    assert!(on_example >= 10, "only {on_example} README and book commands ran on example-out: {ran:#?}");
    assert!(checked.len() >= 5, "flag checks: {checked:#?}");
    let shot = ["shot/defocus.1001.exr", "shot/defocus.1006.exr", "shot/vdslr.1005.exr"];
    for output in ["out.exr", "grads.exr", "fitted.exr", "character.exr", "dbg/coc.png"].iter().chain(&shot) {
        assert!(dir.join("example-out").join(output).is_file(), "example-out/{output} was not written");
    }
}

#[test]
fn the_readme_says_how_to_get_lensblur_on_path_before_using_it() {
    let install = README.find("cargo install --path cli").expect("the README says how to install the binary");
    let first_use = README.find("\n    lensblur ").expect("the README uses lensblur");
    assert!(install < first_use, "`cargo install --path cli` comes after the first `lensblur` command");
}

/// Relative links in the README and the book exist, the book's stay inside its source folder
/// (mdBook copies only that), and the build needs no workspace configuration a crate depending
/// on lensblur would lack (a `.cargo/config.toml` link recipe once made such crates fail to
/// link; tests/out_of_tree.rs builds one).
#[test]
fn every_relative_link_resolves_and_the_build_needs_no_cargo_config() {
    for (name, text) in documents() {
        let folder = Path::new(REPO).join(&name).parent().unwrap().to_path_buf();
        for link in markdown_links(&text).into_iter().filter(|l| !l.contains("://") && !l.starts_with('#')) {
            let file = link.split('#').next().unwrap();
            let target = folder.join(file);
            assert!(target.exists(), "{name} links to missing {link}");
            if name.starts_with("docs/book/") {
                let inside = target.canonicalize().unwrap().starts_with(book_src().canonicalize().unwrap());
                assert!(inside, "{name} links to {link}, outside docs/book/src: the built book lacks it");
            }
        }
    }
    assert!(!Path::new(REPO).join(".cargo/config.toml").exists(), "a .cargo/config.toml applies to this workspace only");
    let toolchain = std::fs::read_to_string(Path::new(REPO).join("docs/TOOLCHAIN.md")).unwrap();
    for needle in ["glslc", "GLSLC"] {
        assert!(toolchain.contains(needle), "docs/TOOLCHAIN.md does not explain '{needle}'");
    }
}

/// SUMMARY.md lists every page of the book and only pages that exist; the README stays short.
#[test]
fn the_book_lists_every_page_and_the_readme_stays_short() {
    let listed = book_pages();
    for page in &listed {
        assert!(page.is_file(), "SUMMARY.md lists missing {}", page.display());
    }
    for entry in std::fs::read_dir(book_src()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "md") && !path.ends_with("SUMMARY.md") {
            assert!(listed.contains(&path), "{} is not in SUMMARY.md", path.display());
        }
    }
    let lines = README.lines().count();
    assert!(lines <= 160, "the README has {lines} lines: move detail into a book page");
}

/// `mdbook build` succeeds (it fails on a page SUMMARY.md names that is missing, and on
/// broken includes). mdBook comes from `.ci/setup` (`cargo install mdbook`).
#[test]
fn the_book_builds_with_mdbook() {
    let out = common::temp_dir("readme", "mdbook");
    let output = Command::new("mdbook")
        .args(["build", "docs/book", "--dest-dir"])
        .arg(&*out)
        .current_dir(REPO)
        .output()
        .unwrap_or_else(|e| panic!("mdbook not found ({e}): run `bash .ci/setup` (it runs `cargo install mdbook`)"));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "mdbook build failed:\n{stderr}");
    assert!(!stderr.contains("WARN") && !stderr.contains("ERROR"), "mdbook warned:\n{stderr}");
    for page in book_pages() {
        let html = page.with_extension("html");
        let built = out.join(html.strip_prefix(book_src()).unwrap());
        assert!(built.is_file(), "mdbook did not write {}", built.display());
    }
}

/// What the README's commands write inside a checkout stays out of `git status`.
#[test]
fn files_the_readme_makes_in_a_checkout_are_ignored() {
    for path in ["example-out/render.exr", "plugins/blender/lensblur.zip", "plugins/blender/lensblur-extension.zip", "lensblur-bundle/template.yaml"] {
        let status = Command::new("git").args(["check-ignore", "-q", path]).current_dir(REPO).status().unwrap();
        assert!(status.success(), "{path} is not in .gitignore");
    }
}

/// The "which method for which input" table names every method, so none is left to trial.
#[test]
fn the_method_table_covers_every_method() {
    let table: Vec<&str> =
        README.lines().skip_while(|l| !l.starts_with("## Which method for which input")).skip(1).skip_while(|l| !l.starts_with('|')).take_while(|l| l.starts_with('|')).collect();
    assert!(table.len() > 3, "no method table in the README");
    let text = table.join("\n");
    for method in Method::ALL {
        assert!(text.contains(&format!("`{}`", method.name())), "the method table does not mention `{}`", method.name());
    }
    assert!(text.contains("thin near structures"), "the table says which method suits thin near structures");
}
