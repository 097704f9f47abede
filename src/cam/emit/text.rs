//! The text of a rewritten line: numbers as the emitter writes them (fixed decimals in the
//! program's units, F as the source writes it) and the rewrite of a line that replaces some
//! of its words and copies the rest byte for byte. Split from `super::emitter` so that the
//! emitter keeps to its one concept, the plan of each line.

use crate::motion::gcode::WordSpan;

use super::emitter::{AXES, CENTRES};

/// Decimals written for a line (4 in mm, 5 in inch).
pub fn decimals(inch: bool) -> usize {
    if inch { 5 } else { 4 }
}

/// `v` rounded to `d` decimals.
pub(super) fn round_to(v: f64, d: usize) -> f64 {
    let s = 10f64.powi(d as i32);
    (v * s).round() / s
}

/// The F word of `f` with `decimals` decimals (and a trailing `.` on a whole number when
/// `dot`), as a source writes it.
pub(super) fn format_feed(f: f64, decimals: usize, dot: bool) -> String {
    let text = format_number(f, decimals);
    if decimals == 0 && dot {
        format!("F{text}.")
    } else {
        format!("F{text}")
    }
}

/// `v` with `d` decimals, never `-0.000`.
pub fn format_number(v: f64, d: usize) -> String {
    let r = round_to(v, d);
    let r = if r == 0.0 { 0.0 } else { r };
    format!("{r:.d$}")
}

pub(super) fn g_times_ten(v: f64) -> u32 {
    (v * 10.0).round().max(0.0) as u32
}

/// Half the output resolution along a 3-D diagonal, mm: the most rounding moves a point.
pub fn rounding_mm(inch: bool) -> f64 {
    let scale = if inch { 25.4 } else { 1.0 };
    0.5 * 10f64.powi(-(decimals(inch) as i32)) * scale * 3f64.sqrt()
}

pub(super) fn is_axis(s: &WordSpan) -> bool {
    AXES.contains(&s.letter)
}

pub(super) fn is_centre(s: &WordSpan) -> bool {
    CENTRES.contains(&s.letter) || s.letter == 'R'
}

pub(super) fn is_motion_g(s: &WordSpan) -> bool {
    s.letter == 'G' && g_times_ten(s.value) <= 30 && g_times_ten(s.value) % 10 == 0
}

/// Words of the line are separated by spaces (or the line has fewer than two words).
pub(super) fn spaced(raw: &str, spans: &[WordSpan]) -> bool {
    spans.len() < 2
        || spans
            .windows(2)
            .any(|w| raw[w[0].end..w[1].start].contains(char::is_whitespace))
}

/// `G1` as the line writes its motion word (`G01` when the source writes `G02`).
pub(super) fn motion_style(raw: &str, spans: &[WordSpan], n: u32) -> String {
    let two = spans
        .iter()
        .find(|s| is_motion_g(s))
        .is_some_and(|s| raw[s.start + 1..s.end].trim_start().starts_with('0'));
    if two {
        format!("G{n:02}")
    } else {
        format!("G{n}")
    }
}

/// `raw` with the words `drop` removed, `words` written where the first dropped word was
/// (after the last word when none is dropped), and the motion word `motion` replacing the
/// line's G0..G3 word or, without one, written after the N word. Everything else (spacing,
/// comments, other words) is copied.
pub fn rewrite(
    raw: &str,
    spans: &[WordSpan],
    drop: impl Fn(&WordSpan) -> bool,
    words: &[String],
    motion: Option<&str>,
) -> String {
    let sep = if spaced(raw, spans) { " " } else { "" };
    let mut out = String::with_capacity(raw.len() + 16);
    let mut cursor = 0;
    let mut inserted = words.is_empty();
    let replace_at = motion.and(spans.iter().position(is_motion_g));
    let insert_before = match (motion, replace_at) {
        (Some(_), None) => spans.iter().position(|s| s.letter != 'N'),
        _ => None,
    };
    for (i, s) in spans.iter().enumerate() {
        let gap = &raw[cursor..s.start];
        if Some(i) == insert_before {
            out.push_str(gap);
            out.push_str(motion.unwrap_or_default());
            out.push_str(sep);
            cursor = s.start;
        }
        let gap = &raw[cursor..s.start];
        if Some(i) == replace_at {
            out.push_str(gap);
            out.push_str(motion.unwrap_or_default());
        } else if drop(s) {
            if !inserted {
                out.push_str(gap);
                out.push_str(&words.join(sep));
                inserted = true;
            } else if !gap.trim().is_empty() {
                out.push_str(gap);
            }
        } else {
            out.push_str(gap);
            out.push_str(&raw[s.start..s.end]);
        }
        cursor = s.end;
    }
    if !inserted {
        if !spans.is_empty() {
            out.push_str(sep);
        }
        out.push_str(&words.join(sep));
    }
    out.push_str(&raw[cursor..]);
    out
}
