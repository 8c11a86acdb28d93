//! Time of the auto-layering alone (`split_into_layers`, issue 43's one-shot cuts) on one flat
//! RGB+Z input, and a hash of the layers it makes, so that two builds can be checked to give
//! the same bytes. A benchmark that prints numbers (median and fastest of RUNS), not a test:
//! - `cargo run --release --example layering_speed -- FLAT.exr RUNS K_PX FOCUS_DISPARITY`: a
//!   flat RGB+Z file (`lensblur render --json` prints the `k_px` and `focus_disparity` it used),
//!   e.g. `bench perf --groups blender`'s `~/.cache/lensblur/perf/*-rgbz-physical.exr`;
//! - `cargo run --release --example layering_speed -- cycles:SCENE_FOLDER[@SCALE] RUNS`: a scene
//!   of the Cycles cache (`~/.cache/lensblur/gt-cache/cycles/<scene>-<size>-<key>`), its pinhole
//!   image and depth upscaled SCALE times (nearest), the lens scaled with it.
use std::path::Path;
use std::time::Instant;

use lensblur::camera::CocModel;
use lensblur::image::Image;
use lensblur::stack::{split_into_layers, AutoLayerOptions};
use lensblur_dev::bench::{cycles::load_scene, BenchCase};
type Failure = Box<dyn std::error::Error>;

fn number<T: std::str::FromStr>(text: Option<String>, what: &str) -> Result<T, Failure> {
    let text = text.ok_or_else(|| format!("missing {what}; usage: layering_speed FLAT.exr RUNS K_PX FOCUS_DISPARITY | cycles:FOLDER[@SCALE] RUNS"))?;
    text.parse().map_err(|_| format!("{what}: not a number: {text:?}").into())
}

fn main() -> Result<(), Failure> {
    let mut args = std::env::args().skip(1);
    let input = args.next().ok_or("usage: layering_speed FLAT.exr RUNS K_PX FOCUS_DISPARITY | cycles:FOLDER[@SCALE] RUNS")?;
    let runs: usize = number(args.next(), "RUNS")?;
    let (image, disparity, coc) = if let Some(rest) = input.strip_prefix("cycles:") {
        let (folder, scale) = match rest.split_once('@') {
            Some((folder, scale)) => (folder, number(Some(scale.to_string()), "SCALE")?),
            None => (rest, 1),
        };
        let truth = load_scene(Path::new(folder))?;
        let (w, h) = (truth.pinhole.width, truth.pinhole.height);
        let image = Image::from_fn(w * scale, h * scale, |x, y| truth.pinhole.get(x / scale, y / scale));
        let small = BenchCase::disparity_of(&truth);
        let disparity: Vec<f32> = (0..w * scale * h * scale).map(|i| small[(i / (w * scale) / scale) * w + (i % (w * scale)) / scale]).collect();
        (image, disparity, CocModel::new(truth.coc.k_px * scale as f32, truth.coc.focus_disparity)?)
    } else {
        let (k_px, focus_disparity): (f32, f32) = (number(args.next(), "K_PX")?, number(args.next(), "FOCUS_DISPARITY")?);
        let (stack, _, _, _) = lensblur::input::read(Path::new(&input), &Default::default())?;
        let [flat] = <[_; 1]>::try_from(stack.layers).map_err(|layers| format!("{input}: {} layers, not one flat image", layers.len()))?;
        (flat.rgba, flat.disparity, CocModel::new(k_px, focus_disparity)?)
    };
    let mut times = Vec::new();
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let stack = split_into_layers(&image, &disparity, &coc, &AutoLayerOptions::default());
        times.push(start.elapsed().as_secs_f64() * 1e3);
        if times.len() == 1 {
            // FNV-1a over every value's bits: equal hashes, equal layers.
            let mut hash = 0xcbf29ce484222325u64;
            for layer in &stack.layers {
                for v in layer.rgba.pixels.iter().flatten().chain(&layer.disparity) {
                    hash = (hash ^ u64::from(v.to_bits())).wrapping_mul(0x100000001b3);
                }
            }
            println!("{}x{}: {} layers, hash {hash:016x}", image.width, image.height, stack.layers.len());
        }
    }
    times.sort_by(f64::total_cmp);
    println!("layering ms: median {:.1}, fastest {:.1} ({} runs)", times[times.len() / 2], times[0], times.len());
    Ok(())
}
