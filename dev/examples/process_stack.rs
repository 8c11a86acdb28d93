//! Writes one of the GPU kit's "process" stacks (`lensblur_dev::bench::process_timings`) to a
//! file and prints the `lensblur render` arguments the kit times it with, so that the host side
//! of a process case (reading, writing) can be profiled on any machine:
//! `cargo run --release -p lensblur-dev --example process_stack -- OUT.exr [WIDTH HEIGHT LAYERS MAX_COC]`
//! (default: the kit's 8K case, 7680 4320 5 40) writes the file, then reads it back and prints
//! both times; `... --example process_stack -- --read FILE.exr [RUNS]` only reads it, RUNS times;
//! `... --example process_stack -- --write-image OUT.exr [RUNS [FROM.exr]]` writes an 8K RGBA
//! image (or FROM.exr's) as `lensblur render` writes its output (float, as without `--half`),
//! RUNS times.
use std::path::PathBuf;
use std::time::Instant;

use lensblur::stack::{read_stack, write_image, write_stack, DepthKind, ReadOptions, SampleType, StackWriteOptions, WriteOptions};
use lensblur_dev::bench::large::{layered_stack, Focus};
type Failure = Box<dyn std::error::Error>;

/// FNV-1a over every layer's name, colour and disparity bits: equal hashes, equal stacks.
fn stack_hash(stack: &lensblur::stack::LayerStack) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    let mut add = |bits: u32| hash = (hash ^ u64::from(bits)).wrapping_mul(0x0100_0000_01b3);
    for layer in &stack.layers {
        layer.name.bytes().for_each(|b| add(u32::from(b)));
        layer.rgba.pixels.iter().flatten().chain(&layer.disparity).for_each(|v| add(v.to_bits()));
    }
    hash
}

fn main() -> Result<(), Failure> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: process_stack OUT.exr [WIDTH HEIGHT LAYERS MAX_COC] | --read FILE.exr [RUNS] | --write-image OUT.exr [RUNS [FROM.exr]]";
    let first = args.next().ok_or(usage)?;
    // Any other word is the output's name: `--help` once wrote an 8K stack by that name.
    if first.starts_with('-') && first != "--read" && first != "--write-image" {
        println!("{usage}");
        return Ok(());
    }
    let read_options = ReadOptions { depth_kind: DepthKind::Disparity, ..ReadOptions::default() };
    if first == "--read" {
        let input = PathBuf::from(args.next().ok_or(usage)?);
        let runs: usize = args.next().map(|t| t.parse()).transpose().map_err(|_| usage)?.unwrap_or(1);
        for _ in 0..runs {
            let start = Instant::now();
            let read = read_stack(&input, &read_options)?;
            let seconds = start.elapsed().as_secs_f64();
            eprintln!("{}: read {} layers in {seconds:.3} s, hash {:016x}", input.display(), read.stack.layers.len(), stack_hash(&read.stack));
        }
        return Ok(());
    }
    if first == "--write-image" {
        let output = PathBuf::from(args.next().ok_or(usage)?);
        let runs: usize = args.next().map(|t| t.parse()).transpose().map_err(|_| usage)?.unwrap_or(1);
        // FROM.exr's image, else a render's kind of content: smooth ramps, a texture, a few bright
        // values (far more compressible than real renders).
        let image = match args.next() {
            Some(from) => lensblur::stack::read_rgba(std::path::Path::new(&from), None, u64::MAX)?,
            None => lensblur::image::Image::from_fn(7680, 4320, |x, y| {
                let v = ((x * 7 + y * 13) % 1000) as f32 / 1000.0 + ((x ^ y) % 17) as f32 * 0.01;
                [v, v * 0.5, 1.0 - v, 1.0]
            }),
        };
        for _ in 0..runs {
            let start = Instant::now();
            write_image(&output, &image, &WriteOptions { sample_type: SampleType::Float, ..WriteOptions::default() })?;
            eprintln!("{}: wrote {}x{} RGBA in {:.3} s", output.display(), image.width, image.height, start.elapsed().as_secs_f64());
        }
        return Ok(());
    }
    let out = PathBuf::from(first);
    let mut number = |default: f64| -> Result<f64, Failure> {
        match args.next() {
            Some(text) => text.parse().map_err(|_| format!("not a number: {text:?}; {usage}").into()),
            None => Ok(default),
        }
    };
    let (width, height, layers, max_coc) =
        (number(7680.0)? as usize, number(4320.0)? as usize, number(5.0)? as usize, number(40.0)? as f32);
    let (stack, lens) = layered_stack(width, height, layers, Focus::FullyDefocused, max_coc)?;
    let options = StackWriteOptions { depth_kind: DepthKind::Disparity, ..StackWriteOptions::default() };
    let start = Instant::now();
    write_stack(&out, &stack, &options)?;
    let written = start.elapsed().as_secs_f64();
    drop(stack);
    let start = Instant::now();
    let read = read_stack(&out, &read_options)?;
    let read_s = start.elapsed().as_secs_f64();
    eprintln!(
        "{}: {width}x{height}, {} layers; write {written:.2} s, read {read_s:.2} s",
        out.display(),
        read.stack.layers.len()
    );
    println!(
        "--device gpu --depth-kind disparity --blur {} --focus-disparity {} --json",
        lens.coc.k_px, lens.coc.focus_disparity
    );
    Ok(())
}
