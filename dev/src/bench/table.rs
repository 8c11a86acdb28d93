//! The report as one text table: a row per method, a column per metric ("mean (worst)").
use std::fmt;

use super::runner::BenchReport;
use lensblur::metrics::Metrics;

/// Decimal places per metric: RMSE-like in [0, 1] need 4, PSNR in dB 2.
const DECIMALS: [usize; 5] = [4, 4, 2, 4, 4];
const COLUMN: usize = 17;

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name_width = self.methods.iter().map(|m| m.name.len()).max().unwrap_or(6).max(6);
        write!(f, "{:<name_width$}  {:<12}", "method", "input")?;
        for name in Metrics::NAMES {
            let label = if name == "PSNR" { "PSNR dB" } else { name };
            write!(f, "{label:>COLUMN$}")?;
        }
        writeln!(f, "{:>20}", "time s (max)")?;
        for m in &self.methods {
            let input = serde_json::to_value(m.input).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default();
            write!(f, "{:<name_width$}  {input:<12}", m.name)?;
            for (i, value) in m.mean.values().iter().enumerate() {
                let cell = format!("{} ({})", number(*value, DECIMALS[i]), number(m.worst[i].value, DECIMALS[i]));
                write!(f, "{cell:>COLUMN$}")?;
            }
            writeln!(f, "{:>20}", format!("{:.3} ({:.3})", m.mean_seconds, m.max_seconds))?;
        }
        writeln!(
            f,
            "mean over {} scene(s) ({}), worst scene in parentheses; time = render only.\n\
             Metrics on sRGB-encoded RGB over black, clipped to [0,1]; SSIM 11x11 Gaussian \
             (sigma 1.5), mean of R,G,B; lower is better for RMSE, RMSE-s; higher for the rest.",
            self.scenes.len(),
            self.scenes.join(", ")
        )
    }
}

fn number(value: f64, decimals: usize) -> String {
    if value.is_finite() {
        format!("{value:.decimals$}")
    } else {
        "inf".into()
    }
}
