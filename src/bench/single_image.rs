//! The single-image table (issue 22): every single-image method and the OpenDefocus peer on
//! every single-image scene in one run, PSNR and render seconds per scene, then the mean and
//! the worst scene. A peer that could not run gets a column of "n/a" and the reason below.
use std::fmt;

use super::peer::{run_opendefocus, PeerRun};
use super::runner::{append_external, run_with_progress, BenchReport};
use super::BenchMethod;
use crate::raytrace::GroundTruth;
use crate::render::InputKind;
use crate::Result;

/// Our single-image methods in the table, in column order after the peer.
pub const SINGLE_IMAGE_METHODS: [&str; 3] = ["drbokeh-auto", "vdslr", "gather"];
/// The peer's column name.
pub const PEER: &str = "opendefocus";

pub struct SingleImageTable {
    pub report: BenchReport,
    /// Why the peer has no column of numbers, if it has none.
    pub peer_missing: Option<String>,
    pub peer_init_seconds: f64,
}

/// Runs `methods` and the peer on `truths`.
pub fn run_single_image(truths: &[GroundTruth], methods: &[BenchMethod], progress: &indicatif::ProgressBar) -> Result<SingleImageTable> {
    let mut report = run_with_progress(truths, methods, progress)?;
    let (peer_missing, peer_init_seconds) = match run_opendefocus(truths) {
        PeerRun::Rendered { renders, init_seconds } => {
            append_external(&mut report, truths, PEER, InputKind::SingleImage, renders)?;
            (None, init_seconds)
        }
        PeerRun::Unavailable(reason) => (Some(reason), 0.0),
    };
    Ok(SingleImageTable { report, peer_missing, peer_init_seconds })
}

impl SingleImageTable {
    /// PSNR of `method` on `scene`, if it ran.
    pub fn psnr(&self, scene: &str, method: &str) -> Option<f64> {
        self.report.cases.iter().find(|c| c.scene == scene && c.method == method).map(|c| c.metrics.psnr)
    }

    fn columns(&self) -> Vec<String> {
        let ran = |n: &str| self.report.methods.iter().any(|m| m.name == n);
        let mut names = vec![PEER.to_string()];
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
        write!(f, "PSNR dB on sRGB over black, clipped to [0,1] (render seconds; worst row: lowest PSNR, longest time).\n{PEER}: ")?;
        match &self.peer_missing {
            Some(reason) => writeln!(f, "n/a, {reason}"),
            None => writeln!(
                f,
                "0.2.2, separate process, exact disk, signed CoC from our thin lens (direct math), Accurate; \
                 its device start-up ({:.2}s) is not in the times",
                self.peer_init_seconds
            ),
        }
    }
}
