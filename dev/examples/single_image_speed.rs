//! Timing of the single-image path at 1024^2 and 4096^2 (issue 22: within 1.5x of its time
//! before the depth-structure layers; issue 46: within 2x of it before the solved matting):
//! a scene's pinhole image and depth upscaled 4x and 16x (nearest), the lens scaled with it;
//! split into layers (on the canvas guessed beyond the frame, as a render job does), then
//! Dr.Bokeh, with the sampled matting of issues 22 and 35 (the layering
//! before issue 46) and the solved one (the default) in the same run. A benchmark that prints
//! numbers (medians of 3 runs), not a test:
//! `cargo run --release --example single_image_speed [CYCLES_SCENE_FOLDER [SCALES]]`, SCALES a
//! comma-separated list of upscales (default `4,16`; `-` for the folder means the default scene).
//! Without a folder,
//! the ray-traced five-planes scene (traced on first use, then read from the bench's
//! ground-truth cache, `~/.cache/lensblur/gt-cache`); with one, a scene of the Cycles cache
//! (`~/.cache/lensblur/gt-cache/cycles/<scene>-<size>-<key>`: a fence is the solver's worst case,
//! every wire pixel is on an edge).
use std::path::PathBuf;
use std::time::Instant;

use lensblur::camera::{Aperture, CocModel};
use lensblur::image::Image;
use lensblur::raytrace::GroundTruth;
use lensblur::render::drbokeh::{DrBokehGpu, Model};
use lensblur::render::Lens;
use lensblur::input::auto_layers;
use lensblur::stack::AutoLayerOptions;
use lensblur_dev::bench::{cycles::load_scene, scenes::single_image_truths, BenchCase};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scales: Vec<usize> = match std::env::args().nth(2) {
        Some(list) => list.split(',').map(str::parse).collect::<Result<_, _>>().map_err(|e| format!("SCALES {list:?}: {e}"))?,
        None => vec![4, 16],
    };
    let truth: GroundTruth = match std::env::args().nth(1).filter(|f| f != "-") {
        Some(folder) => load_scene(&PathBuf::from(folder))?,
        None => {
            let cache = lensblur::cache_dir::user_cache_dir().map(|dir| dir.join("gt-cache"));
            single_image_truths(&["five-planes".into()], false, None, cache.as_deref())?.remove(0)
        }
    };
    let ctx = lensblur::vk::Context::from_env()?;
    let drbokeh = DrBokehGpu::new(&ctx)?;
    for scale in scales {
        let (w, h) = (truth.pinhole.width, truth.pinhole.height);
        let image = Image::from_fn(w * scale, h * scale, |x, y| truth.pinhole.get(x / scale, y / scale));
        let small = BenchCase::disparity_of(&truth);
        let disparity: Vec<f32> = (0..w * scale * h * scale).map(|i| small[(i / (w * scale) / scale) * w + (i % (w * scale)) / scale]).collect();
        let coc = CocModel::new(truth.coc.k_px * scale as f32, truth.coc.focus_disparity).unwrap();
        let lens = Lens { coc, aperture: Aperture::Disk };
        let frame_only = AutoLayerOptions { guess_beyond_frame: false, ..AutoLayerOptions::default() };
        let configurations =
            [("sampled (before)", AutoLayerOptions::sampled()), ("solved, frame only", frame_only), ("solved (default)", AutoLayerOptions::default())];
        for (name, options) in configurations {
            let (mut split, mut render, mut layers) = (Vec::new(), Vec::new(), 0);
            for _ in 0..3 {
                let start = Instant::now();
                // With the canvas guessed beyond the frame, as a render job layers (the
                // default's; the sampled matting before issue 46 has none).
                let (stack, count, _) = auto_layers(&image, &disparity, &coc, &options);
                split.push(start.elapsed().as_secs_f64());
                layers = count;
                let start = Instant::now();
                drbokeh.render(&stack, &lens, Model::DrBokeh)?;
                render.push(start.elapsed().as_secs_f64());
            }
            let (split, render) = (median(split), median(render));
            println!(
                "{}^2 {} {name}: {layers} layers, split {split:.2} s, Dr.Bokeh {render:.2} s, total {:.2} s (medians of 3)",
                w * scale,
                truth.name,
                split + render
            );
        }
    }
    drop(drbokeh);
    ctx.finish()?;
    Ok(())
}
