//! Contour-error pre-compensation of a whole program (CONTRACT v1.1 "Compensated
//! programs", `"contour": true`): [`predistort`](super::predistort()) chooses the G1 points
//! and their feeds, and the emitter writes them in place of each source line's motion,
//! keeping every other word and line of the post's program.

use std::collections::BTreeMap;

use crate::motion::gcode::parse_traced;
use crate::motion::{Machine, ReadOptions};

use super::emit::{Emitter, LinePlan};
use super::error::Error;
use super::predistort::{PredistortOptions, Predistorted, predistort};
use super::program::{Compensated, MAX_OUTPUT_BLOCKS};

/// Iterations the route allows the pre-distortion (it stops earlier once converged).
pub const MAX_ITERATIONS: usize = 12;

/// Rewrites `text` so that `machine`'s servo model, driven by the service's interpolation of
/// the returned program, follows the program's *own* path (Zhang & Chen 2025's model;
/// pre-distortion of the reference, iterated on the exact simulation). Every motion line
/// becomes G1 points (machine frame, mm, written back in the program's units and G90/G91
/// mode) with their F words; other lines and words are copied. Returns the program and the
/// pre-distortion's figures (RMS and max distance of the simulated tool tip to the original
/// path, before and after, mm). Errors: the reader's, and programs the pre-distortion does
/// not handle (rotary axes, dwells).
pub fn contour_program(
    text: &str,
    options: &ReadOptions,
    machine: &Machine,
    period_s: f64,
) -> Result<(Compensated, Predistorted), Error> {
    let (program, reader_warnings, frames) = parse_traced(text, options)?;
    let result = predistort(
        machine,
        &program,
        &PredistortOptions {
            period_s,
            max_iterations: MAX_ITERATIONS,
        },
    )?;
    let mut by_line: BTreeMap<usize, (Vec<[f64; 3]>, Vec<f64>)> = BTreeMap::new();
    for p in &result.points {
        let e = by_line.entry(p.line).or_default();
        e.0.push([p.axes[0], p.axes[1], p.axes.get(2).copied().unwrap_or(0.0)]);
        e.1.push(p.feed_mm_min);
    }
    let mut moved: std::collections::BTreeSet<usize> = std::collections::BTreeSet::new();
    for b in &program.blocks {
        moved.insert(b.line);
    }
    let mut warnings: Vec<String> = reader_warnings.iter().map(|w| w.to_string()).collect();
    let mut em = Emitter::new();
    let mut absorbed = Vec::new();
    for (idx, raw) in text.lines().enumerate() {
        let line = idx + 1;
        let info = em.begin(raw);
        let frame = frames.get(idx).filter(|f| f.line == line);
        let plan = match (by_line.remove(&line), frame) {
            (Some((points_mm, feeds_mm)), Some(f)) => {
                let unit = if f.inch { 25.4 } else { 1.0 };
                LinePlan::Points {
                    points_mm,
                    feeds: Some(feeds_mm.iter().map(|v| v / unit).collect()),
                }
            }
            _ => {
                if moved.contains(&line) && info.moves && !info.machine_move {
                    absorbed.push(line);
                }
                LinePlan::Keep
            }
        };
        em.write(line, raw, &info, frame, plan);
        if em.len() > MAX_OUTPUT_BLOCKS {
            return Err(Error::TooLong {
                limit: MAX_OUTPUT_BLOCKS,
            });
        }
    }
    if !absorbed.is_empty() {
        warnings.push(format!(
            "lines {absorbed:?}: moves shorter than the point spacing kept as programmed"
        ));
    }
    warnings.extend(result.notes.iter().cloned());
    let (lines, source_lines) = em.finish();
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut gcode = lines.join(eol);
    if text.ends_with('\n') {
        gcode.push_str(eol);
    }
    Ok((
        Compensated {
            gcode,
            warnings,
            max_shift_mm: 0.0,
            blocks: lines.len(),
            source_lines,
        },
        result,
    ))
}
