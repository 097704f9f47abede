//! The word rules of [`super`] (**words**): rapids gain no words, no Z word on a 2-D cut
//! and no X/Y word on a Z move in contour mode, a word the source line did not write moves
//! its axis by more than half the last printed digit, and inserted lines carry no N number.

use std::collections::HashSet;

use truecut::cam::decimals;
use truecut::motion::gcode::{Block, LineFrame, WordSpan, word_spans};

use super::check::axis_letters;
use super::{Mv, PRINT_HALF_DIGIT, Reading, Rule};
use crate::compensated::Answered;
use truecut::cam::Compensated;

/// The word rules (module docs of [`super`], **words**).
pub fn words(
    a: &Answered,
    c: &Compensated,
    o: &Reading,
    ans: &Reading,
    blocks: &[Block],
    frames: &[LineFrame],
    v: &mut Vec<(Rule, String)>,
) {
    let src_text: Vec<&str> = a.text.lines().collect();
    let mut firsts = HashSet::new();
    let mut prev_end: Option<[f64; 3]> = None;
    let mut block_i = 0;
    for (i, raw) in c.gcode.lines().enumerate() {
        let line = i + 1;
        let l = c.source_lines[i];
        let first = firsts.insert(l);
        let source = src_text.get(l - 1).copied().unwrap_or("");
        let (sw, aw) = (word_spans(source), word_spans(raw));
        let (s_axes, a_axes) = (axis_letters(&sw), axis_letters(&aw));
        // Where truecut's re-reading is before and after this line.
        let before = prev_end;
        while block_i < blocks.len() && blocks[block_i].line == line {
            prev_end = Some(blocks[block_i].end.xyz);
            block_i += 1;
        }
        let om: Vec<&Mv> = o.moves.iter().filter(|m| m.src == l).collect();
        let rapid = !om.is_empty() && om.iter().all(|m| !m.feed);
        let cycle = om.iter().any(|m| m.feed) && om.iter().any(|m| !m.feed);
        // N numbering.
        let n = |w: &[WordSpan]| w.first().filter(|w| w.letter == 'N').map(|w| w.value);
        if first && n(&sw) != n(&aw) {
            v.push((
                Rule::Words,
                format!(
                    "answer line {line}: N {:?}, the source's {:?}",
                    n(&aw),
                    n(&sw)
                ),
            ));
        }
        if !first && n(&aw).is_some() {
            v.push((
                Rule::Words,
                format!("answer line {line}: an inserted line carries an N number"),
            ));
        }
        if rapid && a_axes.iter().any(|x| !s_axes.contains(x)) {
            v.push((
                Rule::Words,
                format!("answer line {line}: a rapid gained a word: {raw}"),
            ));
        }
        if a.mode == "contour" && !om.is_empty() && om.iter().all(|m| m.feed && m.arc.is_none()) {
            let flat = om.iter().all(|m| m.start[2] == m.end[2]) && !s_axes.contains(&'Z');
            let plunge =
                om.iter().all(|m| m.start[..2] == m.end[..2]) && !s_axes.iter().any(|x| *x != 'Z');
            if flat && a_axes.contains(&'Z') {
                v.push((
                    Rule::Words,
                    format!("answer line {line}: a Z word on a 2-D cut: {raw}"),
                ));
            }
            if plunge && a_axes.iter().any(|x| *x != 'Z') {
                v.push((
                    Rule::Words,
                    format!("answer line {line}: an X/Y word on a Z move: {raw}"),
                ));
            }
            if flat {
                let z = om[0].end[2];
                for q in ans.moves.iter().filter(|m| m.line == line && m.feed) {
                    if (q.end[2] - z).abs() > 2.0 * PRINT_HALF_DIGIT * q.unit_mm {
                        v.push((
                            Rule::Words,
                            format!("answer line {line}: rs274's Z moved on a 2-D cut"),
                        ));
                    }
                }
            }
        }
        // Words the source line did not write move their axis by more than half a digit.
        let own = if first { s_axes.clone() } else { Vec::new() };
        let frame = frames.iter().find(|f| f.line == line);
        let inch = frame.is_some_and(|f| f.inch);
        let half = 0.5 * 10f64.powi(-(decimals(inch) as i32)) * if inch { 25.4 } else { 1.0 };
        let rs_moves: Vec<&Mv> = ans.moves.iter().filter(|m| m.line == line).collect();
        let use_rs = !inch && !rs_moves.is_empty();
        let (from, to) = if use_rs {
            (Some(rs_moves[0].start), rs_moves.last().map(|m| m.end))
        } else {
            (before, prev_end)
        };
        for (k, axis) in ['X', 'Y', 'Z'].iter().enumerate() {
            if !a_axes.contains(axis) || own.contains(axis) || (cycle && *axis == 'Z') {
                continue;
            }
            let moved = match (from, to) {
                (Some(f), Some(t)) => (t[k] - f[k]).abs(),
                _ => f64::INFINITY,
            };
            if moved < half - 1e-9 {
                v.push((
                    Rule::Words,
                    format!(
                        "answer line {line}: {axis} written for a shift of {:.3} µm: {raw}",
                        moved * 1e3
                    ),
                ));
            }
        }
    }
}
