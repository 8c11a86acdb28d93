//! Frame lists as Open Job Description range expressions (`1001-1100`, `1-99:2`, `1,5,9`, and
//! comma-separated mixes), so the chunk a farm hands a task (`Task.Param.Frame` of a
//! `CHUNK[INT]` parameter) passes straight to `--frames`. Same grammar and meaning as OpenJD's
//! own parser (openjd-model `_range_expr.py`): integers may be negative, a range runs from its
//! first to its second number in steps of `:STEP` (negative for a descending range), spaces
//! around the parts are allowed, and the frames are rendered in ascending order.
use crate::{Error, Result};

/// More frames than any shot has; a typo such as `1-10000000` is refused before it allocates.
pub const MAX_FRAMES: usize = 1_000_000;

/// The frames of a range expression, ascending. Frames named twice are an error (OpenJD
/// refuses overlapping ranges), as is an empty expression.
pub fn parse_frames(expression: &str) -> Result<Vec<i64>> {
    let invalid = |why: String| {
        Error::invalid("frame range", format!(
            "frame range '{expression}': {why} (expected e.g. 1001-1100, 1-99:2, 1,5,9 or 1-10,20-30:5)"
        ))
    };
    if expression.trim().is_empty() {
        return Err(invalid("empty".into()));
    }
    let mut frames = Vec::new();
    for element in expression.split(',') {
        let (start, end, step) = parse_element(element.trim()).map_err(&invalid)?;
        // i128: the span of two extreme i64 frames does not fit an i64.
        let count = (i128::from(end) - i128::from(start)) / i128::from(step) + 1;
        if frames.len() as i128 + count > MAX_FRAMES as i128 {
            return Err(invalid(format!("more than {MAX_FRAMES} frames")));
        }
        frames.extend((0..count as i64).map(|i| start + i * step));
    }
    frames.sort_unstable();
    if let Some(pair) = frames.windows(2).find(|pair| pair[0] == pair[1]) {
        return Err(invalid(format!("frame {} is named twice (ranges overlap)", pair[0])));
    }
    Ok(frames)
}

/// One element: `N`, `A-B` or `A-B:STEP`, as (start, end, step) with `end` reached from
/// `start` by whole steps (`1-10:4` ends at 9).
fn parse_element(element: &str) -> std::result::Result<(i64, i64, i64), String> {
    if element.is_empty() {
        return Err("an empty element between commas".into());
    }
    let (range, step) = match element.split_once(':') {
        Some((range, step)) => (range.trim(), Some(parse_integer(step.trim())?)),
        None => (element, None),
    };
    // The separating hyphen is the first one after the start number's own sign.
    let separator = range.char_indices().skip(1).find(|&(_, c)| c == '-').map(|(i, _)| i);
    let Some(separator) = separator else {
        if step.is_some() {
            return Err(format!("'{element}': a step needs a range (A-B:STEP)"));
        }
        let frame = parse_integer(range)?;
        return Ok((frame, frame, 1));
    };
    let start = parse_integer(range[..separator].trim())?;
    let end = parse_integer(range[separator + 1..].trim())?;
    let step = step.unwrap_or(if end >= start { 1 } else { 0 });
    match step {
        0 if end < start => Err(format!("'{element}': a descending range needs a negative step (A-B:-1)")),
        0 => Err(format!("'{element}': the step must not be zero")),
        s if s > 0 && start > end => Err(format!("'{element}': a descending range needs a negative step")),
        s if s < 0 && start < end => Err(format!("'{element}': an ascending range needs a positive step")),
        s => {
            let span = i128::from(end) - i128::from(start);
            // Between start and end, so it fits an i64.
            let last = (i128::from(start) + span / i128::from(s) * i128::from(s)) as i64;
            // Ascending whatever the step's sign: the frames are sorted afterwards anyway.
            Ok(if s > 0 { (start, last, s) } else { (last, start, s.saturating_neg()) })
        }
    }
}

fn parse_integer(text: &str) -> std::result::Result<i64, String> {
    text.parse::<i64>().map_err(|_| format!("'{text}' is not an integer"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn openjd_range_expressions_expand_to_ascending_frames() {
        assert_eq!(parse_frames("1001-1004").unwrap(), [1001, 1002, 1003, 1004]);
        assert_eq!(parse_frames("1-9:2").unwrap(), [1, 3, 5, 7, 9]);
        assert_eq!(parse_frames("1-10:4").unwrap(), [1, 5, 9], "the end is reached by whole steps");
        assert_eq!(parse_frames("9,1,5").unwrap(), [1, 5, 9]);
        assert_eq!(parse_frames(" 1 - 3 , 10-20:5 ,7").unwrap(), [1, 2, 3, 7, 10, 15, 20]);
        assert_eq!(parse_frames("5-1:-2").unwrap(), [1, 3, 5]);
        assert_eq!(parse_frames("-3--1").unwrap(), [-3, -2, -1]);
        assert_eq!(parse_frames("-2-1").unwrap(), [-2, -1, 0, 1]);
        assert_eq!(parse_frames("42").unwrap(), [42]);
    }

    #[test]
    fn malformed_expressions_say_what_is_wrong() {
        for (expression, why) in [
            ("", "empty"),
            ("1,,2", "empty element"),
            ("a-b", "'a' is not an integer"),
            ("5-1", "negative step"),
            ("1-5:-1", "positive step"),
            ("1-5:0", "must not be zero"),
            ("3:2", "needs a range"),
            ("1-5,4", "frame 4 is named twice"),
            ("1-100000000", "more than"),
        ] {
            let message = parse_frames(expression).unwrap_err().to_string();
            assert!(message.contains(why), "'{expression}': {message}");
            assert!(message.contains("expected e.g."), "'{expression}': {message}");
        }
    }
}
