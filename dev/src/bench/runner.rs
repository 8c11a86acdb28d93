//! Runs every (scene, method) pair, times the render and scores it.
use std::time::Instant;

use indicatif::ProgressBar;

use super::methods::{BenchCase, BenchMethod, InputKind};
use lensblur::camera::Aperture;
use lensblur::image::Image;
use lensblur::metrics::{compare, Better, Metrics};
use lensblur::raytrace::GroundTruth;
use lensblur::render::Lens;
use lensblur::{Error, Result};

/// One render scored against its ground truth.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaseResult {
    pub scene: String,
    pub method: String,
    pub metrics: Metrics,
    /// Wall-clock time of the render alone (not the scoring), seconds.
    pub seconds: f64,
}

/// The worst scene of one metric for one method.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Worst {
    pub metric: &'static str,
    pub value: f64,
    pub scene: String,
}

/// One method over all scenes.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MethodSummary {
    pub name: String,
    pub input: InputKind,
    /// Arithmetic mean over scenes of each metric (as the paper's Table 1).
    pub mean: Metrics,
    /// Per metric, the worst value and its scene, in `Metrics::NAMES` order.
    pub worst: Vec<Worst>,
    pub mean_seconds: f64,
    pub max_seconds: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchReport {
    pub scenes: Vec<String>,
    pub methods: Vec<MethodSummary>,
    pub cases: Vec<CaseResult>,
    /// The renders, `renders[scene][method]`, for the contact sheet; not serialised.
    #[serde(skip)]
    pub renders: Vec<Vec<Image>>,
}

/// Runs without a visible progress bar.
pub fn run(scenes: &[GroundTruth], methods: &[BenchMethod]) -> Result<BenchReport> {
    run_with_progress(scenes, methods, &ProgressBar::hidden())
}

/// Runs every method on every scene, advancing `progress` once per pair.
pub fn run_with_progress(scenes: &[GroundTruth], methods: &[BenchMethod], progress: &ProgressBar) -> Result<BenchReport> {
    if scenes.is_empty() || methods.is_empty() {
        return Err(Error::invalid("benchmark", "the benchmark needs at least one scene and one method"));
    }
    progress.set_length((scenes.len() * methods.len()) as u64);
    let (mut cases, mut renders) = (Vec::new(), Vec::new());
    for truth in scenes {
        let lens = Lens { coc: truth.coc, aperture: Aperture::Disk };
        let disparity = BenchCase::disparity_of(truth);
        let case = BenchCase { truth, lens: &lens, pinhole_disparity: &disparity };
        let mut scene_renders = Vec::new();
        for method in methods {
            progress.set_message(format!("{} / {}", truth.name, method.name));
            let start = Instant::now();
            let image = (method.render)(&case)?;
            let seconds = start.elapsed().as_secs_f64();
            let metrics = compare(&image, &truth.defocused)?;
            cases.push(CaseResult { scene: truth.name.clone(), method: method.name.into(), metrics, seconds });
            scene_renders.push(image);
            progress.inc(1);
        }
        renders.push(scene_renders);
    }
    progress.finish_and_clear();
    let summaries = methods.iter().map(|m| summarise(m.name, m.input, &cases)).collect();
    Ok(BenchReport { scenes: scenes.iter().map(|s| s.name.clone()).collect(), methods: summaries, cases, renders })
}

/// Adds a method that ran outside the registry (a peer program) with its renders, one per
/// scene in the report's order, and the seconds it measured for each.
pub fn append_external(report: &mut BenchReport, truths: &[GroundTruth], name: &'static str, input: InputKind, renders: Vec<(Image, f64)>) -> Result<()> {
    if renders.len() != report.scenes.len() || truths.len() != report.scenes.len() {
        return Err(Error::internal(format!("{name}: {} renders for {} scenes", renders.len(), report.scenes.len())));
    }
    for (i, ((image, seconds), truth)) in renders.into_iter().zip(truths).enumerate() {
        let metrics = compare(&image, &truth.defocused)?;
        report.cases.push(CaseResult { scene: truth.name.clone(), method: name.into(), metrics, seconds });
        report.renders[i].push(image);
    }
    let summary = summarise(name, input, &report.cases);
    report.methods.push(summary);
    Ok(())
}

fn summarise(name: &str, input: InputKind, cases: &[CaseResult]) -> MethodSummary {
    let mine: Vec<&CaseResult> = cases.iter().filter(|c| c.method == name).collect();
    let n = mine.len() as f64;
    let mut mean = [0.0f64; 5];
    let mut worst: Vec<Worst> = Vec::new();
    for (i, (&metric, &better)) in Metrics::NAMES.iter().zip(&Metrics::BETTER).enumerate() {
        mean[i] = mine.iter().map(|c| c.metrics.values()[i]).sum::<f64>() / n;
        let is_worse = |a: f64, b: f64| match better {
            Better::Lower => a > b,
            Better::Higher => a < b,
        };
        let mut pick = mine[0];
        for &c in &mine[1..] {
            if is_worse(c.metrics.values()[i], pick.metrics.values()[i]) {
                pick = c;
            }
        }
        worst.push(Worst { metric, value: pick.metrics.values()[i], scene: pick.scene.clone() });
    }
    MethodSummary {
        name: name.into(),
        input,
        mean: Metrics::from_values(mean),
        worst,
        mean_seconds: mine.iter().map(|c| c.seconds).sum::<f64>() / n,
        max_seconds: mine.iter().map(|c| c.seconds).fold(0.0, f64::max),
    }
}
