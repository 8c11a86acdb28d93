//! Device time per compute shader (`LENSBLUR_PROFILE=1`): with it, every [`super::CommandBatch`]
//! writes a timestamp after each dispatch and adds the time since the previous one to that
//! shader's total; the CLI prints the table on exit. Every dispatch is followed by a full
//! barrier, so consecutive timestamps bracket one dispatch (plus any copy or fill recorded
//! before it). Off by default: the timestamps serialise what a GPU could overlap.
use std::sync::{Mutex, OnceLock};

/// Dispatches timed per submission; later ones in a very long batch go untimed.
pub(crate) const MAX_TIMED_DISPATCHES: u32 = 1024;

/// Whether `LENSBLUR_PROFILE` is set (read once).
pub fn enabled() -> bool {
    static ENABLED: OnceLock<bool> = OnceLock::new();
    *ENABLED.get_or_init(|| std::env::var("LENSBLUR_PROFILE").is_ok_and(|v| !v.is_empty() && v != "0"))
}

/// Per shader: name, total device nanoseconds, dispatches.
static TOTALS: Mutex<Vec<(&'static str, f64, u64)>> = Mutex::new(Vec::new());

pub(crate) fn add(shader: &'static str, nanoseconds: f64) {
    let mut totals = TOTALS.lock().unwrap_or_else(|e| e.into_inner());
    match totals.iter_mut().find(|(name, ..)| *name == shader) {
        Some(entry) => {
            entry.1 += nanoseconds;
            entry.2 += 1;
        }
        None => totals.push((shader, nanoseconds, 1)),
    }
}

/// The table of device time per shader, longest first; None when nothing was timed.
pub fn report() -> Option<String> {
    let mut totals = TOTALS.lock().unwrap_or_else(|e| e.into_inner()).clone();
    if totals.is_empty() {
        return None;
    }
    totals.sort_by(|a, b| b.1.total_cmp(&a.1));
    let all: f64 = totals.iter().map(|t| t.1).sum();
    let mut text = format!("{:<34} {:>10} {:>6} {:>11}\n", "shader (LENSBLUR_PROFILE)", "device ms", "share", "dispatches");
    for (name, ns, count) in &totals {
        text += &format!("{name:<34} {:>10.1} {:>5.1}% {count:>11}\n", ns / 1e6, 100.0 * ns / all.max(1.0));
    }
    text += &format!("{:<34} {:>10.1}\n", "total", all / 1e6);
    Some(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn totals_add_up_per_shader_longest_first() {
        add("profile_test_short", 1e6);
        add("profile_test_long", 3e6);
        add("profile_test_short", 1e6);
        let text = report().expect("something was timed");
        let long = text.find("profile_test_long").expect("listed");
        let short = text.find("profile_test_short").expect("listed");
        assert!(long < short, "longest first:\n{text}");
        let line = text.lines().find(|l| l.starts_with("profile_test_short")).unwrap();
        let fields: Vec<&str> = line.split_whitespace().collect();
        assert_eq!((fields[1], fields[3]), ("2.0", "2"), "{line}");
    }
}
