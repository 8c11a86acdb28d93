//! The progress display of `render` and `grad`: a spinner with what is happening and the
//! elapsed time on stderr (hidden under --json), and the tile count of tiled GPU passes.
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// A ticking spinner, or a hidden one when stdout carries a JSON report.
pub fn spinner(hidden: bool) -> ProgressBar {
    let bar = if hidden { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg} {elapsed}").unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// A `RenderOptions::progress` callback that shows "`what`: tile done/total" on `bar` while a
/// frame runs in several tiles (a one-tile frame keeps `what`).
pub fn tiles(bar: &ProgressBar, what: String) -> impl Fn(usize, usize) + Sync + '_ {
    bar.set_message(what.clone());
    move |done, total| {
        if total > 1 {
            bar.set_message(format!("{what}: tile {done}/{total}"));
        }
    }
}
