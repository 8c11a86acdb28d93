//! Writes what auto-layering makes of a Cycles bench scene's pinhole image, one layer per
//! stack layer (a Blender multilayer EXR), to look at the mattes and fills by eye:
//! `cargo run --example autolayer_dump -- SCENE_FOLDER OUT.exr [sampled]` (a folder of the Cycles
//! cache, `~/.cache/lensblur/gt-cache/cycles/<scene>-<size>-<key>`).
use std::path::PathBuf;

use lensblur::stack::{split_into_layers, write_stack, AutoLayerOptions, StackWriteOptions};
use lensblur_dev::bench::{cycles::load_scene, BenchCase};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [folder, out, rest @ ..] = args.as_slice() else {
        return Err("usage: autolayer_dump SCENE_FOLDER OUT.exr [sampled]".into());
    };
    let truth = load_scene(&PathBuf::from(folder))?;
    let disparity = BenchCase::disparity_of(&truth);
    let options = if rest.iter().any(|a| a == "sampled") { AutoLayerOptions::sampled() } else { AutoLayerOptions::default() };
    let stack = split_into_layers(&truth.pinhole, &disparity, &truth.coc, &options);
    write_stack(&PathBuf::from(out), &stack, &StackWriteOptions::default())?;
    println!("{} layers -> {out}", stack.layers.len());
    Ok(())
}
