//! OpenDefocus 0.2.2 as a benchmark peer of lensblur (`lensblur bench single-image`).
//!
//! A separate program, so that lensblur never links this EUPL-1.2 crate: the benchmark writes
//! each scene as a raw frame (see [`read_frame`]), runs this binary once over all of them and
//! reads the renders back. Settings follow shared/TOOLCHAIN.md: Depth mode with
//! `use_direct_math`, so the depth input is a per-pixel signed CoC radius in pixels (positive
//! = nearer than focus) that the benchmark computes from its own thin lens, exactly; a plain
//! disk filter (Simple), `Quality::Accurate`, gamma 1, no lens artefacts.
//!
//! Usage: `lensblur-peer-opendefocus IN OUT [IN OUT ...]`. Prints one line per frame:
//! `frame <IN> <seconds>` (render alone), after `init <seconds>` (device and pipelines).
use std::io::{Read, Write};
use std::time::Instant;

use ndarray::{Array2, Array3};
use opendefocus::datamodel::defocus::DefocusMode;
use opendefocus::datamodel::render::{FilterMode, Quality};
use opendefocus::datamodel::Settings;
use opendefocus::OpenDefocusRenderer;

/// "LBPEER1\0", u32 width, u32 height (little endian), RGBA f32 (row-major, premultiplied
/// linear), then for inputs one f32 signed CoC radius per pixel.
const MAGIC: &[u8; 8] = b"LBPEER1\0";

type Fail = Box<dyn std::error::Error>;

struct Frame {
    width: usize,
    height: usize,
    rgba: Vec<f32>,
    coc: Vec<f32>,
}

fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

fn read_frame(path: &str) -> Result<Frame, Fail> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)?.read_to_end(&mut bytes)?;
    if bytes.len() < 16 || &bytes[..8] != MAGIC {
        return Err(format!("{path}: not a lensblur peer frame").into());
    }
    let dim = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]) as usize;
    let (width, height) = (dim(8), dim(12));
    let n = width * height;
    if bytes.len() != 16 + 20 * n {
        return Err(format!("{path}: {} bytes for a {width}x{height} frame", bytes.len()).into());
    }
    Ok(Frame { width, height, rgba: floats(&bytes[16..16 + 16 * n]), coc: floats(&bytes[16 + 16 * n..]) })
}

fn write_frame(path: &str, width: usize, height: usize, rgba: &[f32]) -> Result<(), Fail> {
    let mut out = Vec::with_capacity(16 + 4 * rgba.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(width as u32).to_le_bytes());
    out.extend_from_slice(&(height as u32).to_le_bytes());
    rgba.iter().for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
    std::fs::File::create(path)?.write_all(&out)?;
    Ok(())
}

fn settings(max_radius: f32) -> Settings {
    let mut settings = Settings::default();
    settings.defocus.set_defocus_mode(DefocusMode::Depth);
    settings.defocus.use_direct_math = true;
    settings.defocus.circle_of_confusion.max_size = max_radius;
    settings.defocus.camera_max_size = max_radius;
    settings.defocus.size_multiplier = 1.0;
    settings.defocus.proxy_scale = Some(1.0);
    settings.defocus.gamma_correction = 1.0;
    settings.render.filter.set_mode(FilterMode::Simple);
    settings.render.set_quality(Quality::Accurate);
    settings.render.set_farm_quality(Quality::Accurate);
    settings
}

fn main() -> Result<(), Fail> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--selftest") {
        return selftest();
    }
    if args.is_empty() || args.len() % 2 != 0 {
        return Err("usage: lensblur-peer-opendefocus IN OUT [IN OUT ...]".into());
    }
    let frames: Vec<Frame> = args.chunks(2).map(|p| read_frame(&p[0])).collect::<Result<_, _>>()?;
    let reach = frames.iter().flat_map(|f| f.coc.iter()).fold(1.0f32, |m, c| m.max(c.abs()));
    let start = Instant::now();
    let mut base = settings(reach.ceil() + 1.0);
    let renderer = pollster::block_on(OpenDefocusRenderer::new(&mut base))?;
    println!("init {:.6}", start.elapsed().as_secs_f64());
    for (frame, pair) in frames.iter().zip(args.chunks(2)) {
        let frame_reach = frame.coc.iter().fold(1.0f32, |m, c| m.max(c.abs()));
        let mut config = base.clone();
        config.defocus.circle_of_confusion.max_size = frame_reach.ceil() + 1.0;
        config.defocus.camera_max_size = frame_reach.ceil() + 1.0;
        let mut image = Array3::from_shape_vec((frame.height, frame.width, 4), frame.rgba.clone())?;
        let coc = Array2::from_shape_vec((frame.height, frame.width), frame.coc.clone())?;
        let start = Instant::now();
        pollster::block_on(renderer.render(config, image.view_mut(), Some(coc), None))?;
        let seconds = start.elapsed().as_secs_f64();
        let rgba: Vec<f32> = image.iter().copied().collect();
        write_frame(&pair[1], frame.width, frame.height, &rgba)?;
        println!("frame {} {seconds:.6}", pair[0]);
    }
    Ok(())
}

/// A disk of radius `r` pixels sampled 16 x 16 per pixel: the exact disk up to 1/256 of a pixel.
fn disk_kernel(r: f32) -> (i32, Vec<f32>) {
    let reach = r.ceil() as i32 + 1;
    let side = (2 * reach + 1) as usize;
    let mut k = vec![0.0f32; side * side];
    for (i, w) in k.iter_mut().enumerate() {
        let (x, y) = ((i % side) as f32 - reach as f32, (i / side) as f32 - reach as f32);
        let inside = (0..256).filter(|s| {
            let (u, v) = (x - 0.5 + ((s % 16) as f32 + 0.5) / 16.0, y - 0.5 + ((s / 16) as f32 + 0.5) / 16.0);
            u * u + v * v <= r * r
        });
        *w = inside.count() as f32;
    }
    let total: f32 = k.iter().sum();
    k.iter_mut().for_each(|w| *w /= total);
    (reach, k)
}

/// Flat planes at constant CoC: OpenDefocus against the exact disk convolution, PSNR over the
/// interior (the borders differ by edge handling). Prints one line per radius and sign.
fn selftest() -> Result<(), Fail> {
    let (w, h) = (96usize, 96usize);
    let texture = |x: usize, y: usize| -> [f32; 4] {
        let v = if (x / 5 + y / 7) % 2 == 0 { 0.9 } else { 0.1 };
        let spot = if (x % 23 == 11) && (y % 19 == 9) { 20.0 } else { 0.0 };
        [v + spot, 0.5 * v, 0.2 + 0.3 * ((x * y) % 3) as f32, 1.0]
    };
    let source: Vec<f32> = (0..w * h).flat_map(|i| texture(i % w, i / w)).collect();
    let mut base = settings(20.0);
    let renderer = pollster::block_on(OpenDefocusRenderer::new(&mut base))?;
    for signed in [2.5f32, 6.0, 11.3, -4.0, -9.7] {
        let mut image = Array3::from_shape_vec((h, w, 4), source.clone())?;
        let coc = Array2::from_elem((h, w), signed);
        pollster::block_on(renderer.render(settings(signed.abs().ceil() + 1.0), image.view_mut(), Some(coc), None))?;
        let (reach, kernel) = disk_kernel(signed.abs());
        let side = (2 * reach + 1) as usize;
        let (mut sq, mut n) = (0.0f64, 0usize);
        let margin = reach as usize + 2;
        for y in margin..h - margin {
            for x in margin..w - margin {
                for c in 0..3 {
                    let mut acc = 0.0f32;
                    for (i, k) in kernel.iter().enumerate() {
                        let (sx, sy) = (x as i32 + (i % side) as i32 - reach, y as i32 + (i / side) as i32 - reach);
                        acc += k * source[(sy as usize * w + sx as usize) * 4 + c];
                    }
                    let d = (image[[y, x, c]] - acc).min(1.0).max(-1.0) as f64;
                    sq += d * d;
                    n += 1;
                }
            }
        }
        let psnr = 10.0 * (1.0 / (sq / n as f64)).log10();
        println!("coc {signed:+.1} px: PSNR {psnr:.2} dB against the exact disk of that radius");
    }
    Ok(())
}
