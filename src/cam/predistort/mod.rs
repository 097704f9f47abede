//! Contour-error pre-compensation by pre-distortion of the reference path (issue 14,
//! `contour: true`): the program is rewritten as G01 points at (at least) the programmed feed
//! so that the machine's simulated servo follows the *original* path.
//!
//! Method. The original program is interpolated and simulated once ([`predict_program`],
//! Zhang & Chen 2025 §2–§4); its samples with its corners form the reference polyline
//! (module `reference`). Points are chosen on it (one every [`PERIODS_PER_POINT`] periods where the
//! original cruises, as few as keep chords within [`CHORD_TOL_MM`] where its speed ramps,
//! since every G01 block starts and ends its jerk-limited ramp at zero acceleration, and
//! every corner and the end). Then, iteration `k`: the points `q_k` are emitted as a program of
//! G01 blocks, interpolated by the service's own interpolator and simulated; the foot of each
//! actual tool tip on the reference gives the error vector `y_k(s) − r(s)` at arc parameter `s`,
//! spread onto the points by linear hat weights, and `q_{k+1}(s) = q_k(s) − α·(y_k(s) − r(s))`
//! (the spatial form of the iterative pre-distortion, Zhang & Chen 2025 §4's contour error as
//! the measure), smoothed along the path over [`SMOOTH_PERIODS`] periods of travel (not across
//! corners). Matching by path parameter rather than by time makes the update blind to the
//! along-path lag, which is no contour error. Feeds are scaled by the length ratio of each
//! chord (never below the programmed F, never above what `max_vel` allows), so the compensated
//! program keeps the original timing. A step is taken when it lowers the RMS without raising
//! the max by more than 1 %; a step that does not is retried once with α halved. Iteration
//! stops when the RMS improves by less than 1 % (converged), when the halved step fails too,
//! or after `max_iterations`; the best iterate is returned.
//!
//! Axis limits: a point is not moved when moving it would make a junction of the G01
//! polyline need more than an axis' `max_accel` at the programmed feed (the interpolator would
//! slow down there, a feed reduction the goal forbids), i.e. where the junction speed limit
//! `max_accel·period/|Δ(dq/ds)|` (the interpolator's) falls below both the feed and its value
//! on the undistorted polyline. These refusals happen at sharp corners at full feed, and are
//! reported in the notes.
//!
//! Corners (issue 24): where the junction limit slows the original, the refused iteration
//! leaves the servo's braking lag, which cuts the corner. The corner stage (module `corners`)
//! then splits each such corner point into three (end of braking, carried past, led in) and
//! finds their offsets by pattern search on the same simulation, refusing moves that take the
//! tool into the material (at an inside corner, more than [`GOUGE_LIMIT_MM`] beyond the path
//! outside the turn; the material side from G41/G42, without them every corner an outside
//! corner whose outer side is free: [`predistort_sided`]; an inside corner may stop instead,
//! a G4 dwell at the corner, [`PredistortPoint::dwell_s`]) or past the corner's share of
//! the duration budget ([`PredistortOptions::max_duration_ratio`]); iteration steps that gouge at such a corner, or take the program past the
//! budget, are taken back. Then the corner-window ILC (module `ilc`) moves every point near
//! each such corner (the braking and accelerating stretches with the three split points) by
//! Levenberg–Marquardt steps on the simulation's Jacobian (norm-optimal ILC on the lifted
//! system), under the same gouge rule and 14/15 of the duration budget for both stages together, within
//! a work bound of simulated periods (a note says when it stops there). Where every such
//! corner is an outside corner, smooth loops of 20 µm chords beyond the corners (module
//! `loops`) are tried as well, and kept when they do better within the whole budget.
//! The figures add the distance-weighted RMS (module `measure`), the gouge and the duration.
//! Where a speed ramp runs on an arc, the whole run is repeated with the ramps' points within
//! [`RAMP_CHORD_TOL_MM`] (fewer G01 blocks, each of which restarts the ramp's acceleration)
//! and the better of the two answers kept ([`predistort_sided`]).
//!
//! Bad cases: machines with rotary axes (`xyzac_table`) and programs with dwells (G4) are
//! refused ([`Error::Unsupported`]); blocks of one line that a canned cycle expands take the
//! feed of the line's first block.

mod corners;
mod ilc;
mod limits;
mod loops;
mod measure;
mod notes;
mod options;
mod reference;
mod run;

use std::collections::BTreeMap;

use crate::motion::gcode::{Block, Motion};
use crate::motion::{self, Kinematics, Machine, Program, contour_error, predict_program};
pub use corners::{GOUGE_LIMIT_MM, SEARCH_SHARE};
use limits::{junction_limits, refuse_sharp_junctions, turns_above};
use notes::{corner_notes, loop_notes, refusal_notes, residual_notes, stop_notes};
pub use options::{DEFAULT_MAX_DURATION_RATIO, MAX_DURATION_RATIO, PredistortOptions};
use reference::{Reference, correction, smooth};
use run::{Eval, Run, ceil_to, norm, round_to, sub};

/// Longest program (interpolation periods of the original and of every iterate) the
/// pre-distortion runs: 2,000,000 periods, 33 min of machining at the default 1 ms period.
pub const MAX_PERIODS: usize = 2_000_000;

/// The coarser chord tolerance (mm) of the second run of [`predistort_sided`] where the
/// original ramps its speed on an arc (2 µm).
pub const RAMP_CHORD_TOL_MM: f64 = 2e-3;

/// Interpolation periods between two points where the original runs at its cruise speed.
pub const PERIODS_PER_POINT: usize = 4;

/// Largest distance (mm) of a chord between two points from the original path where the
/// original ramps its speed (0.5 µm).
pub const CHORD_TOL_MM: f64 = 5e-4;

/// Fraction by which a step may lower a junction's speed limit from `max_accel` below both
/// the feed and the undistorted polyline's limit before it is refused (the interpolator then
/// slows down by at most that fraction for a period there).
pub const JUNCTION_SLACK: f64 = 0.005;

/// Half-width of the smoothing of the corrections along the path, in interpolation periods
/// of travel at the programmed feed.
pub const SMOOTH_PERIODS: f64 = 8.0;

/// Turn of the original path at a point (rad, 5°) from which the corrections are not smoothed
/// across it.
pub const BREAK_RAD: f64 = 0.087;

/// Decimals of the returned positions (mm): printed with 4 decimals they reproduce the figures.
pub const POSITION_DECIMALS: i32 = 4;

/// Decimals of the returned feeds (mm/min): printed with 3 decimals they reproduce the figures.
pub const FEED_DECIMALS: i32 = 3;

/// One G01 block of the compensated program.
#[derive(Clone, Debug, PartialEq)]
pub struct PredistortPoint {
    /// Machine-axis target X, Y, Z (mm, rounded to [`POSITION_DECIMALS`]), the order of
    /// `machine.axes`.
    pub axes: Vec<f64>,
    /// Feed of the G01 block, mm/min (≥ the programmed feed of `line`; rounded up to
    /// [`FEED_DECIMALS`]).
    pub feed_mm_min: f64,
    /// Dwell at the point after the G01 block, s (whole milliseconds; 0: none): the stop the
    /// corner stage makes at an inside corner (module `corners`), written as `G4 P<ms>`.
    pub dwell_s: f64,
    /// 1-based source line of the original block this point replaces (part of).
    pub line: usize,
}

/// The side of the programmed path the material lies on, looking along the direction of
/// travel (G41, tool left of the path: [`MaterialSide::Right`]; G42: [`MaterialSide::Left`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialSide {
    /// Material on the left of the direction of travel.
    Left,
    /// Material on the right of the direction of travel.
    Right,
}

/// Contour error of a simulated run against the original programmed path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorStats {
    /// RMS over the interpolation periods of the distance from the actual tool tip to the
    /// original path, mm.
    pub rms_mm: f64,
    /// Largest such distance, mm.
    pub max_mm: f64,
    /// RMS of that distance along the actual tool tip's path (each period weighted by the
    /// path length covered around it; issue 24's measure), mm.
    pub rms_distance_mm: f64,
    /// Largest distance of the tool tip beyond the original path into the material side of a
    /// corner the junction limit slows (outside the turn at an inside corner, into the turn
    /// at an outside corner), within 1 mm of path of the corner, mm (≤ 0: none).
    pub gouge_mm: f64,
    /// Duration of the command (interpolation periods × period), s.
    pub duration_s: f64,
}

/// The compensated program and what it achieves.
#[derive(Clone, Debug, PartialEq)]
pub struct Predistorted {
    /// The G01 points, in order (the machine starts where the original program starts).
    pub points: Vec<PredistortPoint>,
    /// Contour error of the original program (as [`predict_program`] reports it).
    pub original: ErrorStats,
    /// Contour error of the returned points, interpolated and simulated as the service
    /// would, measured against the original path.
    pub compensated: ErrorStats,
    /// Pre-distortion iterations run (simulations after the first of the undistorted points).
    pub iterations: usize,
    /// Sentences on where the pre-distortion could not help, and why.
    pub notes: Vec<String>,
}

/// Everything that can go wrong in the pre-distortion.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// The program or the machine cannot be simulated (G-code, machine, period, length).
    #[error(transparent)]
    Motion(#[from] motion::Error),
    /// An option is out of its range.
    #[error("{field}: {message}")]
    Option {
        /// The option's name.
        field: &'static str,
        /// Its allowed range.
        message: String,
    },
    /// The program or the machine uses something the pre-distortion does not handle yet.
    #[error("{0}")]
    Unsupported(String),
}

/// Rewrites `program` as G01 points at no less than its feeds so that `machine`'s simulated
/// servo follows the original path, by iterated pre-distortion of the reference path (module
/// docs); returns the points with the original's and the compensated contour error (RMS and
/// max distance of the simulated tool tip to the original path, mm, Zhang & Chen 2025 §4.2
/// eq. 11 by [`contour_error`]) and notes on where it could not help.
/// Errors: [`Error::Motion`] for programs the motion core refuses, [`Error::Option`] for
/// options out of range, [`Error::Unsupported`] for rotary axes and dwells.
pub fn predistort(
    machine: &Machine,
    program: &Program,
    opts: &PredistortOptions,
) -> Result<Predistorted, Error> {
    predistort_keeping(machine, program, opts, &|_| false)
}

/// [`predistort`] with the lines for which `keep(line)` holds written as programmed: their
/// blocks (rapids, canned cycles) are simulated as the original's, their points never move
/// and no corner stage acts at their ends (the caller writes those lines unchanged, so the
/// iteration must see the motion the written program will make: a rapid is one G0 block,
/// not G01 points at the rapid rate).
pub fn predistort_keeping(
    machine: &Machine,
    program: &Program,
    opts: &PredistortOptions,
    keep: &dyn Fn(usize) -> bool,
) -> Result<Predistorted, Error> {
    predistort_sided(machine, program, opts, keep, &|_| None)
}

/// [`predistort_keeping`] with the material side of each source line's block, where the
/// program says it (`side(line)`, from G41/G42): a corner turning towards the material is an
/// outside corner (the command may loop out beyond it), one turning away from it an inside
/// corner (the tool never goes more than [`GOUGE_LIMIT_MM`] beyond the path outside it);
/// corners of lines with no side are outside corners (module docs).
///
/// Run twice where it matters: with the points of the original's speed ramps chosen within
/// [`CHORD_TOL_MM`] and within [`RAMP_CHORD_TOL_MM`] (the second run only when that gives
/// other points, i.e. where a ramp runs on an arc). Until the interpolator's look-ahead
/// carried the acceleration across junctions that need no slowing (session 19), every G01
/// point of a ramp restarted its jerk-limited acceleration from zero, so the fine points made
/// the ramp longer and left the corner stages less of the time budget; now that holds only
/// where a chain of points is split (neighbouring points of unequal feeds, one of them at its
/// feed). The coarse points cost up to that tolerance in chord error. The answer is the run with the lower sum of the two
/// gate ratios (distance-weighted RMS and max against the original's); `iterations` counts
/// both runs.
pub fn predistort_sided(
    machine: &Machine,
    program: &Program,
    opts: &PredistortOptions,
    keep: &dyn Fn(usize) -> bool,
    side: &dyn Fn(usize) -> Option<MaterialSide>,
) -> Result<Predistorted, Error> {
    let fine = predistort_at(machine, program, opts, keep, side, CHORD_TOL_MM)?
        .expect("the fine run always runs");
    if opts.max_iterations == 0 {
        return Ok(fine);
    }
    let Some(coarse) = predistort_at(machine, program, opts, keep, side, RAMP_CHORD_TOL_MM)? else {
        return Ok(fine);
    };
    let score = |p: &Predistorted| {
        p.compensated.rms_distance_mm / p.original.rms_distance_mm.max(1e-12)
            + p.compensated.max_mm / p.original.max_mm.max(1e-12)
    };
    let iterations = fine.iterations + coarse.iterations;
    let best = if score(&coarse) < score(&fine) {
        coarse
    } else {
        fine
    };
    Ok(Predistorted { iterations, ..best })
}

/// One run of [`predistort_sided`] with the ramps' points chosen within `chord_tol_mm`;
/// `None` when that tolerance is not [`CHORD_TOL_MM`] and gives the same points.
fn predistort_at(
    machine: &Machine,
    program: &Program,
    opts: &PredistortOptions,
    keep: &dyn Fn(usize) -> bool,
    side: &dyn Fn(usize) -> Option<MaterialSide>,
    chord_tol_mm: f64,
) -> Result<Option<Predistorted>, Error> {
    opts.check()?;
    if !matches!(machine.kinematics, Kinematics::Xyz) {
        return Err(Error::Unsupported(
            "contour pre-distortion handles xyz machines only so far; this machine has rotary axes"
                .into(),
        ));
    }
    if let Some(b) = program
        .blocks
        .iter()
        .find(|b| matches!(b.motion, Motion::Dwell { .. }))
    {
        return Err(Error::Unsupported(format!(
            "line {}: a dwell (G4) cannot be expressed as G01 points; split the program at the dwell",
            b.line
        )));
    }
    let orig = predict_program(machine, program, opts.period_s, MAX_PERIODS)?;
    let reference = Reference::new(machine, program, &orig.commanded);
    let idx = reference.choose_points(PERIODS_PER_POINT, chord_tol_mm);
    if chord_tol_mm != CHORD_TOL_MM
        && idx == reference.choose_points(PERIODS_PER_POINT, CHORD_TOL_MM)
    {
        return Ok(None);
    }
    let round3 = |p: [f64; 3]| p.map(|v| round_to(v, POSITION_DECIMALS));
    let start = reference.knots[0];
    let lines: Vec<usize> = idx[1..].iter().map(|&k| reference.line[k]).collect();
    let mut kept: BTreeMap<usize, Vec<Block>> = BTreeMap::new();
    for b in &program.blocks {
        if keep(b.line) {
            kept.entry(b.line).or_default().push(b.clone());
        }
    }
    // A kept line's last point is its last block's end (where the written line ends).
    let pts0: Vec<[f64; 3]> = idx[1..]
        .iter()
        .enumerate()
        .map(|(j, &k)| {
            let last_of_line = lines.get(j + 1) != lines.get(j);
            match kept.get(&lines[j]) {
                Some(b) if last_of_line => round3(b[b.len() - 1].end.xyz),
                _ => round3(reference.knots[k]),
            }
        })
        .collect();
    let fixed: Vec<bool> = lines.iter().map(|l| kept.contains_key(l)).collect();
    let mut prev = start;
    let base_len: Vec<f64> = pts0
        .iter()
        .map(|p| {
            let l = norm(sub(*p, prev));
            prev = *p;
            l
        })
        .collect();
    let mut run = Run {
        machine,
        period_s: opts.period_s,
        base_feed: idx[1..].iter().map(|&k| reference.feed_mm_min[k]).collect(),
        sigma: idx[1..].iter().map(|&k| reference.cum[k]).collect(),
        base_len,
        start,
        orig_periods: orig.commanded.t.len(),
        reference,
        lines: lines.clone(),
        kept,
        dwell_s: Vec::new(),
        time_budget: opts.max_duration_ratio - 1.0,
    };
    let init_limits = junction_limits(machine, opts.period_s, start, &pts0);
    let half_mm: Vec<f64> = run
        .base_feed
        .iter()
        .map(|f| SMOOTH_PERIODS * opts.period_s * f / 60.0)
        .collect();
    let breaks = turns_above(start, &pts0, BREAK_RAD);
    let mut cur = pts0.clone();
    let mut cur_eval = run.evaluate(&cur)?;
    // Corners the junction limit slows (module `corners`): the iteration may not take the
    // tool further beyond the path outside them than GOUGE_LIMIT_MM (or than it already went).
    let mut spots = if opts.max_iterations > 0 {
        corners::find_corners(
            &run.reference,
            &idx,
            &pts0,
            start,
            &init_limits,
            &run.base_feed,
            side,
        )
    } else {
        Vec::new()
    };
    spots.retain(|c| !fixed[c.k] && !fixed.get(c.k + 1).copied().unwrap_or(false));
    let gouge_cap: Vec<f64> = corners::score(&run.reference, &spots, &cur_eval)
        .iter()
        .map(|s| s.gouge.max(0.9 * GOUGE_LIMIT_MM))
        .collect();
    let mut alpha = 1.0;
    let mut iterations = 0;
    let mut converged = false;
    let mut refused: Vec<(usize, usize)> = vec![(0, 0); cur.len()];
    let m = cur.len();
    while iterations < opts.max_iterations {
        let corr = smooth(
            &correction(&run.sigma, &cur_eval.feet),
            &run.sigma,
            &half_mm,
            &breaks,
        );
        let mut cand: Vec<[f64; 3]> = (0..m)
            .map(|k| {
                if k + 1 == m || fixed[k] {
                    cur[k]
                } else {
                    round3(std::array::from_fn(|d| cur[k][d] - alpha * corr[k][d]))
                }
            })
            .collect();
        refuse_sharp_junctions(&run, &init_limits, &cur, &mut cand, &mut refused);
        iterations += 1;
        let mut e = run.evaluate(&cand)?;
        // Steps that gouge at a corner are taken back over that corner's window.
        for _ in 0..3 {
            let sc = corners::score(&run.reference, &spots, &e);
            let bad: Vec<usize> = (0..spots.len())
                .filter(|&c| sc[c].gouge > gouge_cap[c])
                .collect();
            if bad.is_empty() {
                break;
            }
            for k in 0..m {
                if bad
                    .iter()
                    .any(|&c| (spots[c].lo..=spots[c].hi).contains(&run.sigma[k]))
                {
                    cand[k] = cur[k];
                }
            }
            iterations += 1;
            e = run.evaluate(&cand)?;
        }
        // A step may not take the program past the corner stage's share of the duration
        // budget (issue 24: 1.15× by default).
        let in_time = e.periods as f64
            <= (1.0 + SEARCH_SHARE * run.time_budget) * run.orig_periods as f64
            || e.periods <= cur_eval.periods;
        if e.rms < cur_eval.rms * (1.0 - 1e-9) && e.max <= cur_eval.max * 1.01 + 1e-7 && in_time {
            let gain = (cur_eval.rms - e.rms) / cur_eval.rms;
            cur = cand;
            cur_eval = e;
            if gain < 0.01 {
                converged = true;
                break;
            }
        } else {
            alpha *= 0.5;
            if alpha < 0.5 {
                converged = true;
                break;
            }
        }
    }
    // The corner stage (module `corners`) on the best iterate.
    let refusal = refusal_notes(machine, &lines, &refused);
    let mut lines = lines;
    let mut corner_result = None;
    let mut ilc_bound = None;
    let orig_fig = loops::original_figures(&orig.report.contour_error, &orig.actual);
    let looped = loops::try_loops(&mut run, &cur, &pts0, &spots, orig_fig)?;
    let pre_corner = corners::score(&run.reference, &spots, &cur_eval);
    let mut loop_note = None;
    if !spots.is_empty() {
        let sigma0 = run.sigma.clone();
        let next = |v: &[f64], k: usize| v[(k + 1).min(v.len() - 1)];
        run.base_feed = corners::split_values(&run.base_feed, &spots, |k| {
            [run.base_feed[k], next(&run.base_feed, k)]
        });
        run.base_len = corners::split_values(&run.base_len, &spots, |_| [0.0, 0.0]);
        run.sigma = corners::split_values(&run.sigma, &spots, |k| [run.sigma[k]; 2]);
        lines = corners::split_values(&lines, &spots, |k| [lines[k], next_line(&lines, k)]);
        run.lines = lines.clone();
        let (mut res, pts, feeds, dwells, e) =
            corners::search(&run, &cur, &pts0, &sigma0, &spots, run.orig_periods)?;
        iterations += res.simulations;
        run.dwell_s = dwells;
        let fixed_point = |j: usize| run.kept.contains_key(&run.lines[j]);
        let (pts, e, ilc_out) =
            ilc::refine(&run, pts, &feeds, e, &spots, &res.before, &fixed_point)?;
        iterations += ilc_out.simulations;
        ilc_bound = ilc_out.bounded_after;
        res.after = corners::score(&run.reference, &spots, &e);
        cur = pts;
        cur_eval = e;
        corner_result = Some(res);
    }
    if let Some(lp) = looped {
        iterations += lp.simulations;
        if loops::better(&run, &lp, &cur_eval, &spots, &gouge_cap, orig_fig) {
            lp.arrays.install(&mut run);
            lines.clone_from(&lp.arrays.lines);
            let after = corners::score(&run.reference, &spots, &lp.eval);
            let limit = lp.limit(&run, opts.max_duration_ratio);
            loop_note = Some(loop_notes(&spots, &pre_corner, &after, &limit));
            (cur, cur_eval, corner_result, ilc_bound) = (lp.arrays.pts, lp.eval, None, None);
        }
    }
    // The official figure: the motion core's contour error of the best iterate's actual
    // against the original commanded path (padded at rest to the same length).
    let n = cur_eval.actual[0].len();
    let orig_cmd: Vec<Vec<f64>> = orig
        .commanded
        .axes
        .iter()
        .map(|c| {
            let mut c = c.clone();
            let last = *c.last().unwrap_or(&0.0);
            c.resize(n, last);
            c
        })
        .collect();
    let report = contour_error(
        &machine.kinematics,
        &orig_cmd,
        &cur_eval.actual,
        &orig.commanded.corners,
    );
    let compensated = measure::stats(
        &run,
        &spots,
        &report.contour_error,
        &cur_eval.actual,
        cur_eval.periods,
    );
    let original = measure::stats(
        &run,
        &spots,
        &orig.report.contour_error,
        &orig.actual,
        run.orig_periods,
    );
    // The source line of each period of the compensated run (its own line tags: point k's
    // block carries tag k + 1).
    let comp_lines: Vec<usize> = cur_eval
        .line
        .iter()
        .filter_map(|&t| {
            (t as usize)
                .checked_sub(1)
                .and_then(|k| lines.get(k).copied())
        })
        .collect();
    let mut notes = Vec::new();
    if !converged && opts.max_iterations > 0 {
        notes.push(format!(
            "stopped after max_iterations = {} before the RMS stopped improving; more iterations may lower it further",
            opts.max_iterations
        ));
    }
    // Lines the corner notes speak for are not named twice.
    let corner_lines: Vec<String> = spots.iter().map(|c| format!("line {}:", c.line)).collect();
    let not_corner = |n: &String| !corner_lines.iter().any(|l| n.starts_with(l.as_str()));
    notes.extend(refusal.into_iter().filter(not_corner));
    if let Some(res) = &corner_result {
        notes.extend(stop_notes(&spots, res, &run.dwell_s));
        notes.extend(corner_notes(&spots, res, opts.max_duration_ratio));
    }
    notes.extend(loop_note.into_iter().flatten());
    if let (Some(steps), Some(first)) = (ilc_bound, spots.first()) {
        notes.push(format!(
            "line {}: the corner-window refinement of this corner and the program's {} others \
             stopped after {steps} of its {} steps at its work bound ({} simulated \
             interpolation periods; each step simulates the whole {:.1} s program once per \
             moving point and direction): compensating a shorter section of the program \
             around its corners lets it run every step",
            first.line,
            spots.len() - 1,
            ilc::MAX_STEPS,
            ilc::WORK_PERIODS,
            run.orig_periods as f64 * opts.period_s,
        ));
    }
    notes.extend(
        residual_notes(
            &orig.report.contour_error,
            &orig.commanded.line,
            &report.contour_error,
            &comp_lines,
            &run.reference,
            &|l| run.kept.contains_key(&l),
        )
        .into_iter()
        .filter(not_corner),
    );
    let points = cur
        .iter()
        .zip(&cur_eval.feeds)
        .zip(&lines)
        .enumerate()
        .map(|(k, ((p, f), l))| PredistortPoint {
            axes: p.to_vec(),
            feed_mm_min: *f,
            dwell_s: run.dwell_s.get(k).copied().unwrap_or(0.0),
            line: *l,
        })
        .collect();
    debug_assert!(cur_eval.periods > 0);
    Ok(Some(Predistorted {
        points,
        original,
        compensated,
        iterations,
        notes,
    }))
}

fn next_line(lines: &[usize], k: usize) -> usize {
    lines[(k + 1).min(lines.len() - 1)]
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod tests_corners;
