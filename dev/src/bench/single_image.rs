//! The single-image table (issue 22): every single-image method, the OpenDefocus peer and
//! Blender 3.4's and 5.0's Defocus nodes (issue 38) on every single-image scene in one run, PSNR
//! and render seconds per scene, then the mean and the worst scene. A peer that could not run
//! gets a column of "n/a" and the reason below.
use std::fmt;

use super::blender::{defocus_truths, SINGLE_IMAGE_NODES};
use super::peer::{run_opendefocus, PeerRun};
use super::runner::{append_external, run_with_progress, BenchReport};
use super::BenchMethod;
use lensblur::image::Image;
use lensblur::metrics::{compare, display_encode, DisplayImage};
use lensblur::raytrace::GroundTruth;
use lensblur::render::InputKind;
use lensblur::Result;

/// Our single-image methods in the table, in column order after the peer.
pub const SINGLE_IMAGE_METHODS: [&str; 3] = ["drbokeh-auto", "vdslr", "gather"];
/// The peer's column name.
pub const PEER: &str = "opendefocus";

pub struct SingleImageTable {
    pub report: BenchReport,
    /// Why the peer has no column of numbers, if it has none.
    pub peer_missing: Option<String>,
    pub peer_init_seconds: f64,
    /// Whether Blender's Defocus columns were asked for, and those that could not run, and why.
    pub with_blender: bool,
    pub blender_missing: Vec<(&'static str, String)>,
    /// Per scene, [`local_pick_gain`] of drbokeh-auto against gather (when both ran).
    pub gather_pick_gain: Vec<(String, f64)>,
}

/// Side of the blocks [`local_pick_gain`] picks between.
pub const PICK_BLOCK: usize = 16;

/// What the layered split loses locally to a plain depth-aware gather (issue 22: it must not
/// be worse anywhere): the PSNR gained over `layered` by taking `plain`'s pixels in every
/// [`PICK_BLOCK`]-square block where they are closer to `truth` (an oracle pick, display
/// values as every metric here), in dB. 0 when no block of the plain render is closer.
pub fn local_pick_gain(layered: &Image, plain: &Image, truth: &Image) -> Result<f64> {
    let base = compare(layered, truth)?.psnr;
    let (width, height) = (truth.width, truth.height);
    let [shown_layered, shown_plain, shown_truth] = [layered, plain, truth].map(display_encode);
    let block_error = |shown: &DisplayImage, x0: usize, y0: usize| -> f64 {
        let rows = y0..(y0 + PICK_BLOCK).min(height);
        let pixels = rows.flat_map(|y| (x0..(x0 + PICK_BLOCK).min(width)).map(move |x| y * width + x));
        pixels.map(|i| (0..3).map(|c| f64::from(shown.rgb[i][c] - shown_truth.rgb[i][c]).powi(2)).sum::<f64>()).sum()
    };
    let mut picked = layered.clone();
    for y0 in (0..height).step_by(PICK_BLOCK) {
        for x0 in (0..width).step_by(PICK_BLOCK) {
            if block_error(&shown_plain, x0, y0) < block_error(&shown_layered, x0, y0) {
                for y in y0..(y0 + PICK_BLOCK).min(height) {
                    let row = y * width + x0..y * width + (x0 + PICK_BLOCK).min(width);
                    picked.pixels[row.clone()].copy_from_slice(&plain.pixels[row]);
                }
            }
        }
    }
    Ok(compare(&picked, truth)?.psnr - base)
}

/// Runs `methods` and the peer on `truths`, and with `with_blender` Blender's Defocus nodes
/// (3.4 and 5.0: a Blender process per scene and node).
pub fn run_single_image(truths: &[GroundTruth], methods: &[BenchMethod], progress: &indicatif::ProgressBar, with_blender: bool) -> Result<SingleImageTable> {
    let mut report = run_with_progress(truths, methods, progress)?;
    let (peer_missing, peer_init_seconds) = match run_opendefocus(truths) {
        PeerRun::Rendered { renders, init_seconds } => {
            append_external(&mut report, truths, PEER, InputKind::SingleImage, renders)?;
            (None, init_seconds)
        }
        PeerRun::Unavailable(reason) => (Some(reason), 0.0),
    };
    let mut blender_missing = Vec::new();
    let blender_dir = lensblur::cache_dir::cache_subdir("single-image-blender");
    for (node, column) in SINGLE_IMAGE_NODES.into_iter().filter(|_| with_blender) {
        match defocus_truths(node, truths, &blender_dir) {
            Ok(renders) => append_external(&mut report, truths, column, InputKind::SingleImage, renders)?,
            Err(e) => blender_missing.push((column, e.to_string())),
        }
    }
    let render_of = |scene: usize, name: &str| {
        let method = report.methods.iter().position(|m| m.name == name)?;
        report.renders.get(scene)?.get(method)
    };
    let mut gather_pick_gain = Vec::new();
    for (scene, truth) in truths.iter().enumerate() {
        if let (Some(layered), Some(plain)) = (render_of(scene, "drbokeh-auto"), render_of(scene, "gather")) {
            gather_pick_gain.push((truth.name.clone(), local_pick_gain(layered, plain, &truth.defocused)?));
        }
    }
    Ok(SingleImageTable { report, peer_missing, peer_init_seconds, with_blender, blender_missing, gather_pick_gain })
}

impl SingleImageTable {
    /// PSNR of `method` on `scene`, if it ran.
    pub fn psnr(&self, scene: &str, method: &str) -> Option<f64> {
        self.report.cases.iter().find(|c| c.scene == scene && c.method == method).map(|c| c.metrics.psnr)
    }

    fn columns(&self) -> Vec<String> {
        let ran = |n: &str| self.report.methods.iter().any(|m| m.name == n);
        let mut names = vec![PEER.to_string()];
        names.extend(SINGLE_IMAGE_NODES.iter().map(|(_, column)| column.to_string()).filter(|n| ran(n)));
        names.extend(SINGLE_IMAGE_METHODS.iter().filter(|n| ran(n)).map(|n| n.to_string()));
        let rest: Vec<String> = self.report.methods.iter().map(|m| m.name.clone()).filter(|n| !names.contains(n)).collect();
        names.extend(rest);
        names
    }
}

const CELL: usize = 18;

impl fmt::Display for SingleImageTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let columns = self.columns();
        let name_width = self.report.scenes.iter().map(String::len).max().unwrap_or(5).max(6);
        write!(f, "{:<name_width$}", "scene")?;
        columns.iter().try_for_each(|c| write!(f, "{c:>CELL$}"))?;
        writeln!(f)?;
        for scene in &self.report.scenes {
            write!(f, "{scene:<name_width$}")?;
            for method in &columns {
                let case = self.report.cases.iter().find(|c| &c.scene == scene && &c.method == method);
                let cell = case.map_or("n/a".into(), |c| format!("{:.2} ({:.2}s)", c.metrics.psnr, c.seconds));
                write!(f, "{cell:>CELL$}")?;
            }
            writeln!(f)?;
        }
        for (label, worst) in [("mean", false), ("worst", true)] {
            write!(f, "{label:<name_width$}")?;
            for method in &columns {
                let summary = self.report.methods.iter().find(|m| &m.name == method);
                let cell = summary.map_or("n/a".into(), |m| {
                    if worst {
                        format!("{:.2} ({:.2}s)", m.worst[2].value, m.max_seconds)
                    } else {
                        format!("{:.2} ({:.2}s)", m.mean.psnr, m.mean_seconds)
                    }
                });
                write!(f, "{cell:>CELL$}")?;
            }
            writeln!(f)?;
        }
        writeln!(f, "PSNR dB on sRGB over black, clipped to [0,1] (render seconds; worst row: lowest PSNR, longest time).")?;
        if !self.gather_pick_gain.is_empty() {
            let gains: Vec<String> = self.gather_pick_gain.iter().map(|(scene, gain)| format!("{scene} +{gain:.2}")).collect();
            writeln!(
                f,
                "Where drbokeh-auto loses locally to gather (PSNR of an oracle pick of gather's {PICK_BLOCK}x{PICK_BLOCK} blocks \
                 closer to the truth, dB): {}",
                gains.join(", ")
            )?;
        }
        write!(f, "{PEER}: ")?;
        match &self.peer_missing {
            Some(reason) => writeln!(f, "n/a, {reason}"),
            None => writeln!(
                f,
                "0.2.2, separate process, exact disk, signed CoC from our thin lens (direct math), Accurate; \
                 its device start-up ({:.2}s) is not in the times",
                self.peer_init_seconds
            ),
        }?;
        if !self.with_blender {
            return Ok(());
        }
        writeln!(
            f,
            "blender-3.4, blender-5.0: the Defocus compositor node (CPU, circle) on the pinhole render and its planar Z, \
             set up for each scene's camera (dev/src/bench/blender.rs); seconds are its compositing time inside Blender"
        )?;
        self.blender_missing.iter().try_for_each(|(column, reason)| writeln!(f, "{column}: n/a, {reason}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pick_gains_only_where_the_plain_render_is_closer() {
        // A flat grey truth, so every pixel of an offset render has the same display error.
        let truth = Image::from_fn(40, 24, |_, _| [0.3, 0.3, 0.3, 1.0]);
        // Off by 0.05 everywhere: no block of a render off by 0.1 is closer.
        let layered = Image::from_fn(40, 24, |x, y| truth.get(x, y).map(|v| v + 0.05));
        let worse = Image::from_fn(40, 24, |x, y| truth.get(x, y).map(|v| v + 0.1));
        assert_eq!(local_pick_gain(&layered, &worse, &truth).unwrap(), 0.0);
        assert_eq!(local_pick_gain(&layered, &layered, &truth).unwrap(), 0.0);
        // Exact in one 16x16 block (and a cut block at the edge): the pick takes those.
        let better = Image::from_fn(40, 24, |x, y| if x < 16 && y < 16 || x >= 32 { truth.get(x, y) } else { worse.get(x, y) });
        let gain = local_pick_gain(&layered, &better, &truth).unwrap();
        // The picked blocks' error vanishes: 256 + 8 * 24 = 448 of 960 pixels, so the MSE falls
        // to 512/960 of the layered one's and the PSNR rises by 10 log10(960/512) dB.
        let expected = 10.0 * (960.0f64 / 512.0).log10();
        assert!((gain - expected).abs() < 0.05, "{gain} vs {expected}");
    }
}
