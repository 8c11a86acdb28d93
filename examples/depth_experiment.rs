//! Runs the depth-from-defocus experiment with the GaussPSF renderer until the CLI has
//! `lensblur fit-depth`: `cargo run --release --example depth_experiment -- [scale] [iterations] [scene...]`;
//! env `LR`, `SMOOTH`, `HSSIM`, `SIGMA_PER_RADIUS` override the learning rate, two loss
//! weights and GaussPSF's sigma/CoC ratio.
use lensblur::optim::{experiment_truths, format_results, run_experiment, ExperimentOptions, FitOptions};
use lensblur::render::gausspsf::GaussPsf;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scale = args.first().map(|s| s.parse()).transpose()?.unwrap_or(0.625);
    let iterations = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(200);
    let names: Vec<String> = args.iter().skip(2).cloned().collect();
    let learning_rate = std::env::var("LR").ok().map(|s| s.parse()).transpose()?.unwrap_or(FitOptions::default().learning_rate);
    let mut fit = FitOptions { iterations, learning_rate, ..FitOptions::default() };
    if let Ok(w) = std::env::var("SMOOTH") {
        fit.weights.smoothness = w.parse()?;
    }
    if let Ok(w) = std::env::var("HSSIM") {
        fit.weights.hssim = w.parse()?;
    }
    let options = ExperimentOptions { scale, fit, ..ExperimentOptions::default() };
    let truths = experiment_truths(&names, &options)?;
    let mut renderer = GaussPsf::default();
    if let Ok(c) = std::env::var("SIGMA_PER_RADIUS") {
        renderer.sigma_per_radius = c.parse()?;
    }
    let results = run_experiment(&renderer, &truths, &options.fit, |scene, i, loss| {
        if i % 25 == 0 {
            eprintln!("{scene} {i:4} loss {loss:.5}");
        }
    })?;
    print!("{}", format_results(&results));
    println!("{}", serde_json::to_string(&results)?);
    Ok(())
}
