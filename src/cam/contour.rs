//! Contour-error pre-compensation of a whole program (CONTRACT v1.1 "Compensated
//! programs", `"contour": true`): [`predistort`](super::predistort()) chooses the G1 points
//! and their feeds of the feed moves, and the emitter writes them in place of each source
//! line's motion, keeping every other word and line of the post's program.
//!
//! What stays as the post wrote it, so that the answer is a valid program (issue 24 item 3):
//! - Rapids stay G0 lines, to their programmed end points (volumetric-compensated when both
//!   are asked): a rapid cuts nothing, so its contour error is no error on the part.
//! - Canned cycles stay cycles (one motion code a line, R, Q, P and the programmed feed kept):
//!   the plunge is a straight move along one axis, which has no contour error to correct.
//! - G28/G30/G53 lines are copied.
//!
//! The pre-distortion still sees the whole path (rapids and cycle moves included; the dwells
//! of cycles, which sit at a standstill, left out), and the figures returned are those of the
//! program as written: it is read back, interpolated and simulated, and its tool tip measured
//! against the original path.
//!
//! Notes and warnings name source lines; with volumetric compensation too
//! ([`volumetric_and_contour`]), the lines of the volumetric pass's text are mapped back to
//! the source's.

use std::collections::BTreeMap;

use crate::motion::gcode::{parse_traced, parse_with};
use crate::motion::program::{Block, Feed, Motion};
use crate::motion::{
    Machine, Program, ReadOptions, contour_error, interpolate, predict_program, simulate_machine,
};

use super::emit::{Emitter, LinePlan};
use super::error::Error;
use super::field::ErrorField;
use super::predistort::{
    self, ErrorStats, MAX_PERIODS, MaterialSide, PredistortOptions, Predistorted, predistort_sided,
};
use super::program::{Compensated, MAX_OUTPUT_BLOCKS, compensate_program, line_list};

/// Iterations the route allows the pre-distortion (it stops earlier once converged).
pub const MAX_ITERATIONS: usize = 12;

/// Rewrites `text` so that `machine`'s servo model, driven by the service's interpolation of
/// the returned program, follows the program's *own* path (Zhang & Chen 2025's model;
/// pre-distortion of the reference, iterated on the exact simulation). Every feed move
/// (G1/G2/G3) becomes G1 points (machine frame, mm, written back in the program's units and
/// G90/G91 mode) with their F words; rapids stay G0 to their end points, canned cycles stay
/// cycles, other lines and words are copied (module docs). Returns the program and its
/// figures (RMS and max distance of the simulated tool tip to the original path, before and
/// after, mm, of the program as written). Errors: the reader's, and programs the
/// pre-distortion does not handle (rotary axes, G4 dwells).
pub fn contour_program(
    text: &str,
    options: &ReadOptions,
    machine: &Machine,
    period_s: f64,
    max_duration_ratio: f64,
) -> Result<(Compensated, Predistorted), Error> {
    let pass = contour_pass(text, options, machine, period_s, max_duration_ratio, None)?;
    let mut out = pass.out;
    let mut warnings = pass.reader_warnings;
    warnings.append(&mut out.warnings);
    out.warnings = warnings;
    Ok((out, pass.result))
}

/// Volumetric compensation against `field` within `tolerance_mm` (see
/// [`compensate_program`]), then the contour pre-distortion of its answer on `machine` (see
/// [`contour_program`]): the path the servo should follow is the volumetric-compensated one.
/// Warnings (the reader's once, the volumetric pass's, the contour pass's) and
/// `source_lines` name the lines of `text`; `max_shift_mm` is the volumetric pass's.
pub fn volumetric_and_contour(
    text: &str,
    options: &ReadOptions,
    field: &dyn ErrorField,
    tolerance_mm: f64,
    machine: &Machine,
    period_s: f64,
    max_duration_ratio: f64,
) -> Result<(Compensated, Predistorted), Error> {
    let v = compensate_program(text, options, field, tolerance_mm)?;
    let pass = contour_pass(
        &v.gcode,
        options,
        machine,
        period_s,
        max_duration_ratio,
        Some(&v.source_lines),
    )?;
    let mut out = pass.out;
    let mut warnings = v.warnings;
    warnings.append(&mut out.warnings);
    out.warnings = warnings;
    out.max_shift_mm = v.max_shift_mm;
    Ok((out, pass.result))
}

/// One contour pass: the program (warnings: the pass's own notes), the reader's warnings on
/// `text`, and the figures.
struct Pass {
    out: Compensated,
    reader_warnings: Vec<String>,
    result: Predistorted,
}

/// What a line of the pass's input is to the contour pass.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// Copied (no motion, G28/G30/G53, lines the reader placed nowhere).
    Other,
    /// A rapid (G0) to this end, machine frame, mm.
    Rapid([f64; 3]),
    /// A canned-cycle hole.
    Hole,
    /// A feed move: pre-distorted.
    Feed,
}

/// `s` with a leading "line N" naming line `map(N)` instead.
fn map_leading_line(s: &str, map: &dyn Fn(usize) -> usize) -> String {
    let Some(rest) = s.strip_prefix("line ") else {
        return s.to_string();
    };
    let digits = rest.chars().take_while(char::is_ascii_digit).count();
    match rest[..digits].parse::<usize>() {
        Ok(n) => format!("line {}{}", map(n), &rest[digits..]),
        Err(_) => s.to_string(),
    }
}

/// The line a note names and its kind (the words that follow, up to the first number).
fn note_key(s: &str) -> Option<(usize, String)> {
    let rest = s.strip_prefix("line ")?;
    let digits = rest.chars().take_while(char::is_ascii_digit).count();
    let line = rest[..digits].parse().ok()?;
    let kind = rest[digits..]
        .chars()
        .take_while(|c| !c.is_ascii_digit())
        .collect();
    Some((line, kind))
}

/// Source lines, each once, in order.
fn unique(mut lines: Vec<usize>) -> Vec<usize> {
    lines.sort_unstable();
    lines.dedup();
    lines
}

/// The contour pass over `text`; `source_lines` maps its lines (1-based, index − 1) to the
/// lines the notes must name (the volumetric pass's map), `None` for the identity.
fn contour_pass(
    text: &str,
    options: &ReadOptions,
    machine: &Machine,
    period_s: f64,
    max_duration_ratio: f64,
    source_lines: Option<&[usize]>,
) -> Result<Pass, Error> {
    let src = |l: usize| {
        source_lines
            .and_then(|m| m.get(l.wrapping_sub(1)).copied())
            .unwrap_or(l)
    };
    let (program, reader_warnings, frames) = parse_traced(text, options)?;
    let raw_lines: Vec<&str> = text.lines().collect();
    let mut by_line: Vec<Vec<&Block>> = vec![Vec::new(); raw_lines.len() + 1];
    for b in &program.blocks {
        if let Some(v) = by_line.get_mut(b.line) {
            v.push(b);
        }
    }
    // What each line is, from the words (the emitter's own reading) and the blocks.
    let mut probe = Emitter::new();
    // The material side each line's moves cut on (G41: tool left, material right; G42:
    // material left; G40 or neither: unknown), modal from line to line.
    let mut comp: Option<MaterialSide> = None;
    let mut sides: Vec<Option<MaterialSide>> = vec![None; raw_lines.len() + 1];
    let kinds: Vec<Kind> = std::iter::once(Kind::Other)
        .chain(raw_lines.iter().enumerate().map(|(idx, raw)| {
            let info = probe.begin(raw);
            for s in info.spans.iter().filter(|s| s.letter == 'G') {
                match (s.value * 10.0).round() as i64 {
                    400 => comp = None,
                    410 => comp = Some(MaterialSide::Right),
                    420 => comp = Some(MaterialSide::Left),
                    _ => {}
                }
            }
            sides[idx + 1] = comp;
            let blocks = &by_line[idx + 1];
            if info.machine_move || blocks.is_empty() {
                Kind::Other
            } else if info.is_hole() {
                Kind::Hole
            } else if blocks
                .iter()
                .all(|b| b.motion == Motion::Linear && b.feed == Feed::Rapid)
            {
                Kind::Rapid(blocks[blocks.len() - 1].end.xyz)
            } else {
                Kind::Feed
            }
        }))
        .collect();
    // The dwells of cycles stand still at the hole bottom: left out of the pre-distortion.
    let path = Program {
        blocks: program
            .blocks
            .iter()
            .filter(|b| {
                !(matches!(b.motion, Motion::Dwell { .. })
                    && kinds.get(b.line) == Some(&Kind::Hole))
            })
            .cloned()
            .collect(),
        first_a_line: program.first_a_line,
        first_c_line: program.first_c_line,
    };
    // Lines written as programmed (rapids, cycles, copied moves) are simulated as such.
    let keep = |l: usize| kinds.get(l).is_some_and(|k| *k != Kind::Feed);
    let side = |l: usize| sides.get(l).copied().flatten();
    let mut result = predistort_sided(
        machine,
        &path,
        &PredistortOptions {
            period_s,
            max_iterations: MAX_ITERATIONS,
            max_duration_ratio,
        },
        &keep,
        &side,
    )
    .map_err(|e| match e {
        predistort::Error::Unsupported(m) => {
            predistort::Error::Unsupported(map_leading_line(&m, &src))
        }
        e => e,
    })?;
    // Per source line: its points (mm), their feeds (mm/min) and stops (s).
    type LinePoints = (Vec<[f64; 3]>, Vec<f64>, Vec<f64>);
    let mut points: BTreeMap<usize, LinePoints> = BTreeMap::new();
    for p in &result.points {
        let e = points.entry(p.line).or_default();
        e.0.push([p.axes[0], p.axes[1], p.axes.get(2).copied().unwrap_or(0.0)]);
        e.1.push(p.feed_mm_min);
        e.2.push(p.dwell_s);
    }
    let mut em = Emitter::new();
    let (mut absorbed, mut rapids, mut holes) = (Vec::new(), Vec::new(), Vec::new());
    for (idx, raw) in raw_lines.iter().enumerate() {
        let line = idx + 1;
        let info = em.begin(raw);
        let frame = frames.get(idx).filter(|f| f.line == line);
        let pts = points.remove(&line);
        let plan = match (kinds[line], frame) {
            (_, None) | (Kind::Other, _) => LinePlan::Keep,
            (Kind::Rapid(end_mm), Some(_)) => {
                rapids.push(src(line));
                LinePlan::Move { end_mm }
            }
            (Kind::Hole, Some(_)) => {
                holes.push(src(line));
                LinePlan::Keep
            }
            (Kind::Feed, Some(f)) => match pts {
                Some((points_mm, feeds_mm, dwells_s)) => {
                    let unit = if f.inch { 25.4 } else { 1.0 };
                    LinePlan::Points {
                        points_mm,
                        feeds: Some(feeds_mm.iter().map(|v| v / unit).collect()),
                        dwells_s,
                    }
                }
                None => {
                    absorbed.push(src(line));
                    LinePlan::Keep
                }
            },
        };
        em.write(line, raw, &info, frame, plan);
        if em.len() > MAX_OUTPUT_BLOCKS {
            return Err(Error::TooLong {
                limit: MAX_OUTPUT_BLOCKS,
            });
        }
    }
    let mut warnings = Vec::new();
    let mut say = |lines: Vec<usize>, what: &str| {
        let lines = unique(lines);
        if !lines.is_empty() {
            warnings.push(format!("lines {}: {what}", line_list(&lines)));
        }
    };
    say(
        rapids,
        "rapids kept as G0 to their end points, not pre-distorted (a rapid does not cut)",
    );
    say(
        holes,
        "canned cycles kept as cycles (one motion code a line; R, Q, P and the programmed feed \
         kept), not pre-distorted: the plunge is a straight move along one axis, with no \
         contour error to correct",
    );
    say(
        absorbed,
        "feed moves shorter than the point spacing kept as programmed",
    );
    // Notes on the volumetric pass's lines, mapped: one per source line and kind of note (a
    // split move is many lines of that text); its count of further lines means nothing here.
    let mut said = std::collections::BTreeSet::new();
    for note in &result.notes {
        let mapped = map_leading_line(note, &src);
        if source_lines.is_some() {
            if mapped.starts_with("and ") {
                continue;
            }
            if let Some(key) = note_key(&mapped)
                && !said.insert(key)
            {
                continue;
            }
        }
        warnings.push(mapped);
    }
    let (lines, out_lines) = em.finish();
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut gcode = lines.join(eol);
    if text.ends_with('\n') {
        gcode.push_str(eol);
    }
    let cutting = |l: usize| matches!(kinds.get(l), Some(Kind::Feed | Kind::Hole));
    let (original, compensated) = figures(
        &program, &gcode, &out_lines, options, machine, period_s, &cutting,
    )?;
    // The gouge at the corners is the pre-distortion's own figure (it knows the corners; it
    // simulates the kept lines as they are written).
    result.original = ErrorStats {
        gouge_mm: result.original.gouge_mm,
        ..original
    };
    result.compensated = ErrorStats {
        gouge_mm: result.compensated.gouge_mm,
        ..compensated
    };
    Ok(Pass {
        out: Compensated {
            gcode,
            warnings,
            max_shift_mm: 0.0,
            blocks: lines.len(),
            source_lines: out_lines.into_iter().map(src).collect(),
        },
        reader_warnings: reader_warnings.iter().map(|w| w.to_string()).collect(),
        result,
    })
}

/// Contour error (RMS and max distance of the simulated tool tip to the original path, mm;
/// Zhang & Chen 2025 §4.2 eq. 11 by [`contour_error`]) of the `original` program and of the
/// program text `written` (read with `options`), both interpolated and simulated on `machine`
/// at `period_s` (s); the shorter run is held at rest at its end. Taken over the periods in
/// which each run runs a line that cuts (`cutting`, of a line of the original text: feed
/// moves and holes; rapids cut nothing and are not pre-distorted; line `k` of `written` came
/// from line `written_lines[k - 1]` of that text), over all periods when no line cuts. Each
/// run is judged by its own lines: the written program may run a little longer, and its
/// periods then no longer line up with the original's.
fn figures(
    original: &Program,
    written: &str,
    written_lines: &[usize],
    options: &ReadOptions,
    machine: &Machine,
    period_s: f64,
    cutting: &dyn Fn(usize) -> bool,
) -> Result<(ErrorStats, ErrorStats), Error> {
    let sim = |e: crate::motion::Error| Error::Contour(predistort::Error::Motion(e));
    let orig = predict_program(machine, original, period_s, MAX_PERIODS).map_err(sim)?;
    let (program, _) = parse_with(written, options)?;
    let cmd = interpolate(&program, machine, period_s, MAX_PERIODS).map_err(sim)?;
    let mut actual = simulate_machine(machine, &cmd).map_err(sim)?;
    let n = actual[0].len().max(orig.commanded.t.len());
    let pad = |cols: &mut Vec<Vec<f64>>| {
        for c in cols.iter_mut() {
            let last = *c.last().unwrap_or(&0.0);
            c.resize(n, last);
        }
    };
    let mut orig_cmd = orig.commanded.axes.clone();
    pad(&mut orig_cmd);
    pad(&mut actual);
    let report = contour_error(
        &machine.kinematics,
        &orig_cmd,
        &actual,
        &orig.commanded.corners,
    );
    // A period cuts when its run is on a cutting line then (at rest after its end: not).
    let cuts = |tags: &[u32], to_text: &dyn Fn(usize) -> Option<usize>| -> Vec<bool> {
        (0..n)
            .map(|i| {
                tags.get(i)
                    .and_then(|&l| to_text(l as usize))
                    .is_some_and(cutting)
            })
            .collect()
    };
    let mask_orig = cuts(&orig.commanded.line, &|l| Some(l));
    let mask_written = cuts(&cmd.line, &|l| {
        l.checked_sub(1).and_then(|k| written_lines.get(k).copied())
    });
    let all = !mask_orig.contains(&true);
    // Each period weighted by the path length its tool tip covers (half the chord to each
    // neighbour), as the pre-distortion's distance-weighted RMS.
    let weights = |axes: &[Vec<f64>]| -> Vec<f64> {
        let tip = |i: usize| [axes[0][i], axes[1][i], axes[2][i]];
        let m = axes[0].len();
        let d = |a: [f64; 3], b: [f64; 3]| {
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
        };
        (0..m)
            .map(|i| {
                let back = if i > 0 { d(tip(i), tip(i - 1)) } else { 0.0 };
                let fwd = if i + 1 < m {
                    d(tip(i + 1), tip(i))
                } else {
                    0.0
                };
                0.5 * (back + fwd)
            })
            .collect()
    };
    let stats = |ce: &[f64], axes: &[Vec<f64>], periods: usize, mask: &[bool]| {
        let w = weights(axes);
        let (mut sq, mut max, mut k) = (0.0, 0.0f64, 0usize);
        let (mut wsq, mut wsum) = (0.0, 0.0);
        for (i, e) in ce.iter().enumerate() {
            if all || mask.get(i).copied().unwrap_or(false) {
                sq += e * e;
                max = max.max(*e);
                k += 1;
                let wi = w.get(i).copied().unwrap_or(0.0);
                wsq += wi * e * e;
                wsum += wi;
            }
        }
        let rms = (sq / k.max(1) as f64).sqrt();
        ErrorStats {
            rms_mm: rms,
            max_mm: max,
            rms_distance_mm: if wsum > 0.0 { (wsq / wsum).sqrt() } else { rms },
            gouge_mm: 0.0,
            duration_s: periods as f64 * period_s,
        }
    };
    Ok((
        stats(
            &orig.report.contour_error,
            &orig.actual,
            orig.commanded.t.len(),
            &mask_orig,
        ),
        stats(&report.contour_error, &actual, cmd.t.len(), &mask_written),
    ))
}
