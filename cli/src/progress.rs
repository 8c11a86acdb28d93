//! The progress display of `render` and `grad`: a spinner with what is happening and the
//! elapsed time on stderr (hidden under --json), and the tile count of tiled GPU passes.
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};
use lensblur::raytrace::RowProgress;

/// A ticking spinner, or a hidden one when stdout carries a JSON report.
pub fn spinner(hidden: bool) -> ProgressBar {
    let bar = if hidden { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg} {elapsed}").unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// A `RenderOptions::progress` callback that shows "`what` (pass p/P): tile done/total, ~N s
/// left" on `bar`: the pass only when a look takes several renders (`passes`: chromatic
/// channels, cat's-eye nodes), the tiles only when a frame runs in several. A count that starts
/// again is the next pass; the estimate is the mean time per tile so far in this pass, over
/// what is left of it and of the passes after it.
pub fn tiles(bar: &ProgressBar, what: String, passes: usize) -> impl Fn(usize, usize) + Sync + '_ {
    bar.set_message(what.clone());
    let now = Instant::now();
    let state = Mutex::new(PassState { index: 1, start: now, last: now, done: 0 });
    move |done, total| {
        let mut state = state.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let now = Instant::now();
        if done <= state.done {
            // The next pass began when the last one's final tile ended.
            state.index += 1;
            state.start = state.last;
        }
        state.done = done;
        state.last = now;
        if total <= 1 && passes <= 1 {
            return;
        }
        let per_tile = (now - state.start).as_secs_f64() / done.max(1) as f64;
        let passes_after = passes.saturating_sub(state.index);
        let left = per_tile * (total.saturating_sub(done) + passes_after * total) as f64;
        let pass = if passes > 1 { format!(" (pass {}/{passes})", state.index.min(passes)) } else { String::new() };
        let tiles = if total > 1 { format!(": tile {done}/{total}") } else { String::new() };
        bar.set_message(format!("{what}{pass}{tiles}{}", eta(left)));
    }
}

/// Where a multi-pass render is: the pass (1-based), when it began, the last tile's end and
/// how many of its tiles are done.
struct PassState {
    index: usize,
    start: Instant,
    last: Instant,
    done: usize,
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
        let progress = tiles(&bar, "drbokeh".into(), 1);
        assert_eq!(bar.message(), "drbokeh");
        progress(1, 1);
        assert_eq!(bar.message(), "drbokeh", "a one-tile frame keeps the plain message");
        let progress = tiles(&bar, "drbokeh".into(), 1);
        progress(1, 4);
        assert!(bar.message().starts_with("drbokeh: tile 1/4"), "{}", bar.message());
        progress(4, 4);
        assert_eq!(bar.message(), "drbokeh: tile 4/4");
    }

    #[test]
    fn multi_pass_looks_count_their_passes_tiled_or_not() {
        let bar = ProgressBar::hidden();
        // Three one-tile renders (chromatic aberration on a small frame).
        let progress = tiles(&bar, "drbokeh".into(), 3);
        progress(1, 1);
        assert!(bar.message().starts_with("drbokeh (pass 1/3)"), "{}", bar.message());
        progress(1, 1);
        progress(1, 1);
        assert_eq!(bar.message(), "drbokeh (pass 3/3)", "nothing left after the last pass");
        // Two passes of two tiles.
        let progress = tiles(&bar, "drbokeh".into(), 2);
        progress(1, 2);
        progress(2, 2);
        progress(1, 2);
        assert!(bar.message().starts_with("drbokeh (pass 2/2): tile 1/2"), "{}", bar.message());
    }
}

/// The ray tracer's row reports drawn on `bar`.
pub fn rows(bar: &ProgressBar) -> RowProgress {
    let bar = bar.clone();
    RowProgress::new(move |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })
}
