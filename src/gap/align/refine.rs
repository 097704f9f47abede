//! The delay of a time-stamped log refined with the diagnosed effects (issue 23 item 4). The
//! first estimate ([`super::estimate_clock`]) matches the log to the stored simulation alone,
//! so a lag the machine adds and the stored model lacks (a backlash's lost motion after a
//! reversal, a friction's deficit) is partly read as a later start — about 21 µs of a 15 µm
//! play's lag in the HTTP test of the issue, which costs microns on a rapid. Once a diagnosis
//! has named its effects, the delay is chosen again by the diagnosis' own misfit: at every
//! delay tried the log is put on the program's grid afresh and the named effects refitted to
//! it; the delay whose fit leaves the least is kept (a profile of the misfit over the delay).
//!
//! Written here (no crate): a bracket of delays around the first estimate and Brent's line
//! search between the best one's neighbours (`numeric::brent::minimize_on_grid`).

use super::{Aligned, Alignment, Clock, TimedLog, grid};
use crate::gap::Error;
use crate::gap::effects::Effect;
use crate::gap::fit::SimCache;
use crate::gap::motion::MotionDiagnosis;
use crate::gap::steps::{Model, Problem};
use crate::numeric::brent::minimize_on_grid;

/// Half-width of the delay bracket searched around the first estimate, in program periods: the
/// lag an effect hides in the first estimate is a small fraction of a period (21 µs of 1 ms in
/// the test), the bracket leaves room for a hundred times that.
pub const REFINE_PERIODS: f64 = 2.0;
/// Delays tried evenly on the bracket before the line search (odd: the first estimate is one).
const REFINE_GRID: usize = 9;
/// Brent's stopping width as a fraction of the bracket between the best grid delay's
/// neighbours (one period): 1e-3 of a period, 1 µs at 1 ms.
const REFINE_TOL: f64 = 1e-3;
/// Most line-search evaluations after the grid (each refits the effects once).
const REFINE_ITER: usize = 30;

/// The effects of a diagnosis' `steps`, in the order they were added: what [`refine_delay`]
/// refits (empty when no step was taken — the stored simulation is then the whole model, and
/// the first estimate already minimises its misfit).
pub fn step_effects(d: &MotionDiagnosis) -> Vec<Effect> {
    d.steps
        .iter()
        .map(|s| s.fitted.effect())
        .filter(|e| *e != Effect::None)
        .collect()
}

/// The log `timed` put on the program's grid at the delay where `effects`, refitted at every
/// delay tried, fit it best; `first` is its alignment to the stored simulation (the rate ratio
/// is kept). Returns `Aligned` with `delay_s` the refined delay, `delay_stored_s` the first,
/// `refined_with` the effects' names and `residual_effects_rms_mm` the misfit at the refined
/// delay; with no effects, the log placed at the first estimate unchanged.
///
/// Formula: `d* = argmin_d Σ_{i∈S} |log_i − p_d(τ_i(d))|²` with `τ_i(d) = (t_i − d)/rate`,
/// `p_d` the stored simulation plus `effects` fitted jointly (as the diagnosis' steps, additive,
/// two backfitting sweeps) to the log resampled on the grid at delay `d` (observed instants
/// only), read linearly between grid instants; `S` the log samples inside the grid at the first
/// estimate (the same samples at every delay). Searched on `REFINE_PERIODS` periods either
/// side of the first estimate: 9 delays, then Brent's line search between the best one's
/// neighbours to 1e-3 of a period.
/// Reference: profile least squares (the nuisance parameters — the effects' — refitted at each
/// value of the one searched), e.g. Seber & Wild, Nonlinear Regression (1989), §5.9; Brent,
/// Algorithms for Minimization without Derivatives (1973), ch. 5.
/// Known bad cases: effects named wrongly pull the delay towards what they can mimic; a lag
/// alike on every axis at constant feed stays inseparable from a delay (a gain mismatch then
/// keeps part of the first estimate's bias); the minimum at a bracket end is returned as is.
/// Errors: as [`TimedLog::place`] at the refined delay.
pub fn refine_delay(
    timed: &TimedLog,
    first: &Alignment,
    effects: &[Effect],
) -> Result<Aligned, Error> {
    let clock_at = |delay_s: f64| Clock {
        delay_s,
        rate_ratio: first.rate_ratio,
        residual_rms_mm: first.residual_rms_mm,
        motion_rms_mm: 0.0,
    };
    if effects.is_empty() {
        return timed.place(&clock_at(first.delay_s));
    }
    let period = timed.period_s;
    let n_grid = first.grid_samples;
    let base: Vec<Vec<f64>> = timed
        .reference
        .iter()
        .map(|c| c[..n_grid].to_vec())
        .collect();
    let cmd: Vec<Vec<f64>> = timed
        .extended
        .iter()
        .map(|c| c[..n_grid].to_vec())
        .collect();
    let tau0 = timed.program_times(&clock_at(first.delay_s));
    let end = (n_grid - 1) as f64 * period;
    let inside: Vec<usize> = (0..tau0.len())
        .filter(|&i| (0.0..=end).contains(&tau0[i]))
        .collect();
    // a shift of the stamps moves no gap: found once
    let gaps = grid::gaps(&tau0);
    // the re-simulations of the effects' searches depend on the command only: shared by every
    // delay tried
    let cache = SimCache::default();
    let misfit = |d: f64| -> f64 {
        let tau = timed.program_times(&clock_at(d));
        let (measured, observed) =
            grid::resample(&timed.reference, period, &tau, &timed.log, &gaps, n_grid);
        let problem = Problem {
            plants: &timed.plants,
            cmd: &cmd,
            meas: &measured,
            base: &base,
            cache: &cache,
        };
        let model = effects
            .iter()
            .fold(Model::default(), |m, &e| m.with(&problem, e, &observed, 2));
        let pred = model.predict(&base);
        sse_at(&pred, period, &tau, &timed.log, &inside)
    };
    let h = 2.0 * REFINE_PERIODS * period * first.rate_ratio / (REFINE_GRID - 1) as f64;
    let half = (REFINE_GRID / 2) as f64;
    let delays: Vec<f64> = (0..REFINE_GRID)
        .map(|j| first.delay_s + (j as f64 - half) * h)
        .collect();
    let (d, sse) = minimize_on_grid(misfit, &delays, REFINE_ITER, REFINE_TOL / 2.0);
    let clock = Clock {
        residual_rms_mm: (sse_at(
            &timed.reference,
            period,
            &timed.program_times(&clock_at(d)),
            &timed.log,
            &(0..timed.t.len()).collect::<Vec<_>>(),
        ) / timed.t.len() as f64)
            .sqrt(),
        ..clock_at(d)
    };
    let mut aligned = timed.place(&clock)?;
    let a = &mut aligned.alignment;
    a.delay_stored_s = first.delay_s;
    a.refined_with = effects.iter().map(|e| e.name().to_string()).collect();
    a.residual_effects_rms_mm = Some((sse / inside.len().max(1) as f64).sqrt());
    Ok(aligned)
}

/// `Σ_{i∈samples} Σ_k (log_k,i − pred_k(τ_i))²` (mm²), `pred` per axis one value every
/// `period` s from 0, read linearly between instants and held outside.
fn sse_at(pred: &[Vec<f64>], period: f64, tau: &[f64], log: &[Vec<f64>], samples: &[usize]) -> f64 {
    samples
        .iter()
        .map(|&i| {
            pred.iter()
                .zip(log)
                .map(|(p, l)| (l[i] - grid::read(p, period, tau[i])).powi(2))
                .sum::<f64>()
        })
        .sum()
}
