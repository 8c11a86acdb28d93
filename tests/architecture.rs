//! The library's module graph, as the book's architecture page draws it: every top-level module
//! of `src/` has a layer, and a module imports only modules of lower layers (`crate::x` paths
//! in code, not in comments or test modules). So there is no import cycle and nothing imports
//! upward; a new module or a new import that breaks the layering fails here, naming both.
//! Also: `unsafe` is denied at the crate root and allowed only in the Vulkan module and the
//! deep reader's FFI, and the library's manifest names none of the front ends' crates.
use std::collections::BTreeMap;
use std::path::Path;

// The repository root: these tests belong to the cli package (cli/Cargo.toml).
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

/// Bottom to top. A module may import any module of a lower layer, none of its own or above.
const LAYERS: &[&[&str]] = &[
    // Errors: everything returns them.
    &["error"],
    // Leaves: files written whole, the cache folder, the float image, grid maths, SPIR-V.
    &["atomic_file", "cache_dir", "image", "tile_grid", "shaders"],
    // Maths shared by the CPU and GPU paths: the camera model and apertures; image metrics.
    &["camera", "metrics"],
    // Vulkan plumbing.
    &["vk"],
    // Layer stacks and their files (I/O at the edge).
    &["stack"],
    // The rendering methods, the tiler and the backward passes.
    &["render"],
    // What builds on renders: lens character, the ground-truth ray tracer, shots' frame lists.
    &["character", "raytrace", "sequence"],
    // A caller's input (read, camera resolved, auto-layered) and the optimiser.
    &["input", "optim"],
    // One render job: what every front end builds.
    &["job"],
    // A resident session: renders jobs over one input kept on a device.
    &["session"],
];

fn layer_of(module: &str) -> usize {
    LAYERS
        .iter()
        .position(|layer| layer.contains(&module))
        .unwrap_or_else(|| panic!("src/{module} has no layer: add it to LAYERS here and to the architecture page"))
}

/// The `crate::x` modules `text` imports in code: comments dropped, test modules skipped.
fn imports(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        if line.trim_start().starts_with("#[cfg(test)]") {
            break; // test modules sit at the end of a file
        }
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            let name: String = rest[at + 7..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
            if !name.is_empty() && name.chars().next().unwrap().is_ascii_lowercase() {
                found.push(name);
            }
            rest = &rest[at + 7..];
        }
        // `use crate::{a, b::c}`: the braces' first-level names.
        if let Some(group) = code.split("crate::{").nth(1) {
            for part in group.split(',') {
                let name: String = part.trim().chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
                if !name.is_empty() && name.chars().next().unwrap().is_ascii_lowercase() {
                    found.push(name);
                }
            }
        }
    }
    found
}

fn rust_files(path: &Path, out: &mut Vec<std::path::PathBuf>) {
    if path.is_dir() {
        for entry in std::fs::read_dir(path).unwrap() {
            rust_files(&entry.unwrap().path(), out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// Each top-level module of `src/` and the modules it imports, with one file that does.
fn module_graph() -> BTreeMap<String, BTreeMap<String, String>> {
    let src = Path::new(REPO).join("src");
    let mut graph: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for entry in std::fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        let module = path.file_stem().unwrap().to_string_lossy().into_owned();
        if module == "lib" {
            continue;
        }
        let mut files = Vec::new();
        rust_files(&path, &mut files);
        let edges = graph.entry(module.clone()).or_default();
        for file in files {
            for import in imports(&std::fs::read_to_string(&file).unwrap()) {
                if import != module {
                    edges.entry(import).or_insert_with(|| file.strip_prefix(REPO).unwrap_or(&file).display().to_string());
                }
            }
        }
    }
    graph
}

#[test]
fn every_library_module_imports_only_lower_layers() {
    let graph = module_graph();
    assert!(graph.len() >= 15, "found only {} modules: {:?}", graph.len(), graph.keys());
    let mut upward = Vec::new();
    for (module, edges) in &graph {
        for (import, file) in edges {
            if layer_of(import) >= layer_of(module) {
                upward.push(format!("{module} (layer {}) imports {import} (layer {}) in {file}", layer_of(module), layer_of(import)));
            }
        }
    }
    assert!(upward.is_empty(), "imports that do not go down a layer:\n  {}", upward.join("\n  "));
    // The check can fail: the stack once imported the backward passes' gradient types.
    assert!(layer_of("stack") < layer_of("render") && graph["render"].contains_key("stack"));
}

#[test]
fn the_import_scanner_sees_grouped_and_nested_paths_and_skips_comments_and_tests() {
    let text = "use crate::{camera::Aperture, image};\nuse crate::render::Lens; // crate::job\n\
                fn f() { crate::stack::x(); }\n#[cfg(test)]\nmod tests { use crate::input; }";
    let mut found = imports(text);
    found.sort();
    found.dedup();
    assert_eq!(found, ["camera", "image", "render", "stack"]);
}

#[test]
fn unsafe_is_denied_but_in_the_vulkan_module_and_the_deep_ffi() {
    let lib = std::fs::read_to_string(Path::new(REPO).join("src/lib.rs")).unwrap();
    assert!(lib.contains("#![deny(unsafe_code)]"), "src/lib.rs denies unsafe code");
    let mut files = Vec::new();
    rust_files(&Path::new(REPO).join("src"), &mut files);
    let allowed: Vec<String> = files
        .iter()
        .filter(|f| std::fs::read_to_string(f).unwrap().contains("allow(unsafe_code)"))
        .map(|f| f.strip_prefix(REPO).unwrap_or(f).display().to_string())
        .collect();
    let mut allowed: Vec<&str> = allowed.iter().map(|f| f.trim_start_matches("/").trim_start_matches("cli/../")).collect();
    allowed.sort();
    assert_eq!(allowed, ["src/lib.rs", "src/stack/deep/ffi.rs"], "only the crate root's `mod vk` and the FFI module opt in");
    let vk = lib.lines().skip_while(|l| l.trim() != "#[allow(unsafe_code)]").nth(1).unwrap_or("");
    assert_eq!(vk.trim(), "pub mod vk;");
}

#[test]
fn the_library_depends_on_no_front_end_crate() {
    let manifest = std::fs::read_to_string(Path::new(REPO).join("Cargo.toml")).unwrap();
    let dependencies = manifest.split("[dependencies]").nth(1).expect("a [dependencies] table");
    let dependencies = dependencies.split("\n[").next().unwrap();
    for crate_name in ["clap", "indicatif", "anyhow", "ctrlc", "pyo3", "lensblur-dev", "lensblur-cli"] {
        assert!(
            !dependencies.lines().any(|l| l.trim_start().starts_with(&format!("{crate_name} "))),
            "the library depends on {crate_name}"
        );
    }
}
