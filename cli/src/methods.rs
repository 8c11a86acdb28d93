//! `lensblur methods`: every rendering method of the registry, what it reads and which
//! method-specific flags it accepts (`--json` for programs such as the Blender add-on).
use lensblur::render::Method;

use super::method_args::flag;

#[derive(clap::Args)]
#[command(after_help = "Examples:\n  lensblur methods         what each method reads, where it runs, which flags it accepts\n  lensblur methods --json  the same as JSON (the Blender add-on reads it)")]
pub struct Args {
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.json {
        println!("{}", serde_json::to_string_pretty(&listing())?);
        return Ok(());
    }
    for method in Method::ALL {
        let spec = method.spec();
        // The default says so in its summary (which the add-on shows too).
        println!("{}: {}", spec.name, spec.summary);
        let flags: Vec<String> = spec.settings.iter().map(|s| flag(*s)).collect();
        let input = match spec.input {
            lensblur::render::InputKind::Layers => "layers",
            lensblur::render::InputKind::SingleImage => "one image + depth",
        };
        let device = if spec.uses_gpu { "Vulkan" } else { "CPU" };
        let flags = if flags.is_empty() { "none".to_string() } else { flags.join(" ") };
        println!("    reads {input}; runs on {device}; method flags: {flags}");
    }
    Ok(())
}

/// The registry as JSON: one object per method, in registry order.
pub fn listing() -> serde_json::Value {
    let methods: Vec<serde_json::Value> = Method::ALL
        .iter()
        .map(|method| {
            let spec = method.spec();
            serde_json::json!({
                "name": spec.name,
                "label": spec.label,
                "summary": spec.summary,
                "input": spec.input,
                "uses_gpu": spec.uses_gpu,
                "default": *method == Method::default(),
                "flags": spec.settings.iter().map(|s| flag(*s)).collect::<Vec<_>>(),
            })
        })
        .collect();
    serde_json::json!({ "methods": methods })
}

/// The `--method` help: the names from the registry.
pub fn method_help() -> String {
    let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
    format!("Rendering method: {} (`lensblur methods` describes each)", names.join(", "))
}
