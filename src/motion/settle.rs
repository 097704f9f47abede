//! The servo's run-out after a program's last command: the interpolated command ends at the
//! program's end point, but the axes still lag behind it (v/kv on a first-order loop, less the
//! feed-forward; 160 µm on a demo program) and keep moving until the servo settles. A
//! prediction that stops with the command shows a tool that never reaches the end point.
//!
//! [`predict_program_settled`] holds the command at its last sample and simulates on until every
//! axis is within [`SETTLE_TOLERANCE_MM`] (linear) or [`SETTLE_TOLERANCE_DEG`] (rotary) of
//! the end point and stays there, at most [`MAX_SETTLE_S`]; the answer's rows go on to that
//! sample, and [`Settle`] says how long it took. Only the contour-error answers (the route and
//! `truecut contour`) run it: the gap diagnosis is driven by measured samples of its own
//! length, and the pre-distortion and the compensated-program figures judge the periods in
//! which a line runs, so [`super::predict_program`] keeps to the command.

use super::contour::contour_error;
use super::error::Error;
use super::gcode::Program;
use super::interpolate::{Trajectory, interpolate_with};
use super::machine::Machine;
use super::path_control::PathControl;
use super::predict::{ContourPrediction, simulate_linear};

/// How close every linear axis must come to the program's end point for the servo to count as
/// settled, mm (0.1 µm: below what a machine tool's scales resolve, 0.05–1 µm).
pub const SETTLE_TOLERANCE_MM: f64 = 1e-4;

/// The same for a rotary axis, degrees (1e-5°: 0.1 µm at a tool 0.57 m from the axis).
pub const SETTLE_TOLERANCE_DEG: f64 = 1e-5;

/// Longest the simulation runs on after the command ends, s. A servo loop of kv ≥ 1 1/s settles
/// from a 1 mm lag to 0.1 µm within ln(10⁴)/kv ≈ 9.2 s; a slower one is answered with a warning
/// rather than simulated for minutes (the route is synchronous).
pub const MAX_SETTLE_S: f64 = 10.0;

/// First run-out simulated, s; doubled until the servo has settled or [`MAX_SETTLE_S`].
const FIRST_RUN_OUT_S: f64 = 0.5;

/// How the servo came to rest after the command ended.
#[derive(Clone, Debug, PartialEq)]
pub struct Settle {
    /// Time of the command's last sample (the program's end), s.
    pub command_end_s: f64,
    /// Time from the command's end until every axis is within tolerance of the end point and
    /// stays there, s (0 when it already was); [`MAX_SETTLE_S`] when it did not settle.
    pub settle_s: f64,
    /// Whether the servo settled within [`MAX_SETTLE_S`].
    pub settled: bool,
    /// Distance of the machine's linear axes (X, Y, Z) from the end point when the command
    /// ended, mm.
    pub lag_at_command_end_mm: f64,
    /// The same at the answer's last sample, mm.
    pub lag_at_last_sample_mm: f64,
}

impl Settle {
    /// The warning of a servo that did not settle, if it did not.
    pub fn warning(&self) -> Option<String> {
        (!self.settled).then(|| {
            format!(
                "the servo did not settle within {SETTLE_TOLERANCE_MM} mm ({SETTLE_TOLERANCE_DEG}° \
                 on rotary axes) of the program's end point in {MAX_SETTLE_S} s after the command \
                 ended: the tool is still {:.6} mm away at the last sample; the machine's servo \
                 loops are very slow (raise kv) or unstable",
                self.lag_at_last_sample_mm
            )
        })
    }
}

/// The tolerance of axis `k` (X, Y, Z linear; A, C rotary).
fn tolerance(k: usize) -> f64 {
    if k < 3 {
        SETTLE_TOLERANCE_MM
    } else {
        SETTLE_TOLERANCE_DEG
    }
}

/// Distance of the linear axes at sample `i` from `end`, mm.
fn lag_mm(actual: &[Vec<f64>], end: &[f64], i: usize) -> f64 {
    (0..actual.len().min(3))
        .map(|k| (actual[k][i] - end[k]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The first sample from which every axis stays within its tolerance of `end` up to the last
/// simulated one, if the last one is within (none is before `from`).
fn settled_from(actual: &[Vec<f64>], end: &[f64], from: usize) -> Option<usize> {
    let len = actual.first().map_or(0, Vec::len);
    let inside = |i: usize| {
        actual
            .iter()
            .enumerate()
            .all(|(k, col)| (col[i] - end[k]).abs() <= tolerance(k))
    };
    let mut i = len;
    while i > from && inside(i - 1) {
        i -= 1;
    }
    (i < len).then_some(i.max(from))
}

/// `commanded` held at its last sample for `extra` more periods (times, axes and the last
/// line tag continued; no corner is added).
fn held(commanded: &Trajectory, extra: usize) -> Trajectory {
    let mut out = commanded.clone();
    let n = commanded.t.len();
    let last_line = commanded.line.last().copied().unwrap_or(0);
    for k in 1..=extra {
        out.t.push((n - 1 + k) as f64 * commanded.period_s);
        out.line.push(last_line);
    }
    for col in &mut out.axes {
        let last = *col.last().unwrap_or(&0.0);
        col.resize(n + extra, last);
    }
    out
}

/// Predicts the contour error of `program` on `machine` at `period_s` (s; 1e-5..0.1), then
/// simulates on after the command's end until the servo settles (module docs); refuses
/// programs longer than `max_periods` periods (the run-out is not counted).
///
/// What: [`super::predict_program`]'s prediction, its rows continued past the command's end
/// (command held at the end point) to the first sample from which every axis stays within
/// tolerance of the end point, with the [`Settle`] figures.
///
/// Formula: the servo is linear and time-invariant, so simulating the held command from the
/// start gives the same samples up to the command's end as without it; the run-out is
/// simulated over `FIRST_RUN_OUT_S`, doubled (up to [`MAX_SETTLE_S`]) until the axes are
/// within tolerance at its last sample and have stayed there at least as long as they took to
/// get there (so a decaying oscillation that leaves the band again is not cut short). The
/// machine's stored effects are added to that run after settling is judged on the linear servo.
///
/// Reference: openapi.yaml `Servo`; Zhang & Chen 2025 §3 (the servo) and §4 (contour error).
///
/// Known bad cases: an oscillation that stays inside the band for longer than it took to
/// enter it and then leaves it is cut off where it first settled (a linear servo's run-out
/// does not do that unless nearly unstable); a servo slower than [`MAX_SETTLE_S`] is answered
/// unsettled, with [`Settle::warning`].
pub fn predict_program_settled(
    machine: &Machine,
    program: &Program,
    control: &PathControl,
    period_s: f64,
    max_periods: usize,
) -> Result<(ContourPrediction, Settle), Error> {
    let commanded = interpolate_with(program, control, machine, period_s, max_periods)?;
    let n = commanded.t.len();
    let end: Vec<f64> = commanded
        .axes
        .iter()
        .map(|c| *c.last().unwrap_or(&0.0))
        .collect();
    let max_extra = (MAX_SETTLE_S / period_s).ceil() as usize;
    let mut extra = ((FIRST_RUN_OUT_S / period_s).ceil() as usize).min(max_extra);
    let (mut run, mut actual, keep, settled) = loop {
        let run = held(&commanded, extra);
        let actual = simulate_linear(machine, &run)?;
        let from = settled_from(&actual, &end, n - 1);
        let stayed = |k: usize| n + extra - k >= k + 1 - n;
        match from {
            Some(k) if k == n - 1 || stayed(k) => break (run, actual, k + 1, true),
            _ if extra >= max_extra => break (run, actual, n + extra, false),
            _ => extra = (2 * extra).min(max_extra),
        }
    };
    run.t.truncate(keep);
    run.line.truncate(keep);
    for col in run.axes.iter_mut().chain(actual.iter_mut()) {
        col.truncate(keep);
    }
    // settled is judged on the linear servo; the stored effects (which may leave the tool off
    // the end point for good: backlash, scale, drift) are added to the run it asks for
    let actual = machine
        .effects
        .apply(&machine.axis_models(), period_s, &run.axes, actual)?;
    let settle = Settle {
        command_end_s: commanded.t[n - 1],
        settle_s: run.t[keep - 1] - commanded.t[n - 1],
        settled,
        lag_at_command_end_mm: lag_mm(&actual, &end, n - 1),
        lag_at_last_sample_mm: lag_mm(&actual, &end, keep - 1),
    };
    let report = contour_error(&machine.kinematics, &run.axes, &actual, &run.corners);
    Ok((
        ContourPrediction {
            commanded: run,
            actual,
            report,
        },
        settle,
    ))
}

#[cfg(test)]
mod tests;
