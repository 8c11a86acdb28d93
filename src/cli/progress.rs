//! The progress display of `render` and `grad`: a spinner with what is happening and the
//! elapsed time on stderr (hidden under --json), and the tile count of tiled GPU passes.
use std::sync::Mutex;
use std::time::{Duration, Instant};

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

/// A `RenderOptions::progress` callback that shows "`what`: tile done/total, ~N s left" on
/// `bar` while a frame runs in several tiles (a one-tile frame keeps `what`). The estimate is
/// the pass's mean time per tile so far; a count that starts again (the next render of a
/// multi-pass look: chromatic channels, cat's-eye nodes) starts its own estimate.
pub fn tiles(bar: &ProgressBar, what: String) -> impl Fn(usize, usize) + Sync + '_ {
    bar.set_message(what.clone());
    let pass = Mutex::new((Instant::now(), 0usize));
    move |done, total| {
        if total <= 1 {
            return;
        }
        let mut pass = pass.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if done <= pass.1 {
            // A new pass: its first tile's time is unknown, so it ran since the last one ended.
            pass.0 = Instant::now();
        }
        pass.1 = done;
        let left = pass.0.elapsed().as_secs_f64() / done.max(1) as f64 * (total - done.min(total)) as f64;
        bar.set_message(format!("{what}: tile {done}/{total}{}", eta(left)));
    }
}

/// ", ~N s left" (minutes past two minutes); nothing once done.
fn eta(seconds_left: f64) -> String {
    match seconds_left {
        s if s <= 0.0 => String::new(),
        s if s < 120.0 => format!(", ~{:.0} s left", s.ceil()),
        s => format!(", ~{:.0} min left", (s / 60.0).ceil()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eta_reads_in_seconds_then_minutes_and_vanishes_when_done() {
        assert_eq!(eta(0.0), "");
        assert_eq!(eta(4.2), ", ~5 s left");
        assert_eq!(eta(119.0), ", ~119 s left");
        assert_eq!(eta(601.0), ", ~11 min left");
    }

    #[test]
    fn tile_messages_count_tiles_and_estimate_the_rest() {
        let bar = ProgressBar::hidden();
        let progress = tiles(&bar, "drbokeh".into());
        assert_eq!(bar.message(), "drbokeh");
        progress(1, 1);
        assert_eq!(bar.message(), "drbokeh", "a one-tile frame keeps the plain message");
        progress(1, 4);
        assert!(bar.message().starts_with("drbokeh: tile 1/4"), "{}", bar.message());
        progress(4, 4);
        assert_eq!(bar.message(), "drbokeh: tile 4/4");
    }
}
