//! Time of Dr.Bokeh's fast CPU render alone (`drbokeh::native`, what a one-shot render of a
//! small frame runs without a device) on one flat RGB+Z input split into layers as `lensblur
//! render` splits it, or on a layered file's own layers, and a hash of the image, so that two builds can be checked to give the
//! same bytes. A benchmark that prints numbers (median and fastest of RUNS), not a test:
//! `cargo run --release -p lensblur-dev --example cpu_render_speed -- STACK.exr RUNS K_PX FOCUS_DISPARITY`
//! (`lensblur render --json` prints the `k_px` and `focus_disparity` it used).
use std::path::Path;
use std::time::Instant;

use lensblur::camera::{Aperture, CocModel};
use lensblur::render::drbokeh::native::render_native;
use lensblur::render::Lens;
use lensblur::stack::{split_into_layers, AutoLayerOptions, LayerStack};
type Failure = Box<dyn std::error::Error>;

const USAGE: &str = "usage: cpu_render_speed STACK.exr RUNS K_PX FOCUS_DISPARITY";

fn number<T: std::str::FromStr>(text: Option<String>, what: &str) -> Result<T, Failure> {
    let text = text.ok_or_else(|| format!("missing {what}; {USAGE}"))?;
    text.parse().map_err(|_| format!("{what}: not a number: {text:?}").into())
}

fn main() -> Result<(), Failure> {
    let mut args = std::env::args().skip(1);
    let input = args.next().ok_or(USAGE)?;
    let runs: usize = number(args.next(), "RUNS")?;
    let (k_px, focus_disparity): (f32, f32) = (number(args.next(), "K_PX")?, number(args.next(), "FOCUS_DISPARITY")?);
    let (stack, _, _, _) = lensblur::input::read(Path::new(&input), &Default::default())?;
    let coc = CocModel::new(k_px, focus_disparity)?;
    let stack = match <[_; 1]>::try_from(stack.layers) {
        Ok([flat]) => split_into_layers(&flat.rgba, &flat.disparity, &coc, &AutoLayerOptions::default()),
        Err(layers) => LayerStack::new(stack.width, stack.height, layers)?,
    };
    let lens = Lens { coc, aperture: Aperture::Disk };
    let mut times = Vec::new();
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let image = render_native(&stack, &lens, None)?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
        if times.len() == 1 {
            // FNV-1a over every value's bits: equal hashes, equal images.
            let mut hash = 0xcbf29ce484222325u64;
            for v in image.pixels.iter().flatten() {
                hash = (hash ^ u64::from(v.to_bits())).wrapping_mul(0x100000001b3);
            }
            println!("{}x{}, {} layers: hash {hash:016x}", stack.width, stack.height, stack.layers.len());
        }
    }
    times.sort_by(f64::total_cmp);
    println!("render ms: median {:.1}, fastest {:.1} ({} runs)", times[times.len() / 2], times[0], times.len());
    Ok(())
}
