//! Logs whose clock disagrees with the program's (issue 23 item 4): a real log starts before
//! or after the program, samples at its own rate (1 kHz from a servo trace, 10–100 Hz from a
//! data collector), with jitter and gaps. Given the log's own time stamps, this file finds the
//! program time of every log sample from the motion itself — the delay (the log-clock time of
//! the program's start) and, when there is one, the rate ratio of the two clocks — and puts
//! the log on the simulation's time grid for the diagnosis: each grid instant within half a
//! period of a log sample takes the log interpolated there, every other instant is left out of
//! the fit (weight 0) rather than filled in.
//!
//! Written here (no crate): the matching is a least-squares fit of two clock parameters to
//! the stored simulation, read at arbitrary times by linear interpolation — a brute-force
//! coarse scan (positions are absolute, so the scan needs no correlation trick) and a few
//! Gauss–Newton steps.

mod clock;
mod grid;
mod refine;

pub use clock::{Clock, estimate_clock};
pub use grid::{fill_unobserved, masked_stats, observed_only};
pub use refine::{refine_delay, step_effects};

use serde::Serialize;

use crate::gap::Error;
use crate::gap::motion::MotionBlock;
use crate::gap::plant::AxisPlant;

/// Fewest time-stamped samples a log needs before it is aligned at all.
pub const MIN_LOG_SAMPLES: usize = 20;
/// Fewest grid instants the aligned log must observe inside the program's window.
pub const MIN_OBSERVED: usize = 50;
/// Seconds the command is held at its end after the program (the machine settles): the
/// simulation the log is matched to, and the longest the diagnosis runs past the program.
pub const HOLD_S: f64 = 2.0;
/// A step between successive stamps longer than this many times the median step is a gap.
pub const GAP_FACTOR: f64 = 3.0;
/// Most grid instants an aligned log is diagnosed on (the route's synchronous limit).
pub const MAX_GRID_SAMPLES: usize = 100_000;

/// A stretch with no samples, in the log's clock (s): the stamps of the samples either side.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogGap {
    /// Stamp of the last sample before the gap, s.
    pub t_start: f64,
    /// Stamp of the first sample after the gap, s.
    pub t_end: f64,
}

/// How a time-stamped log was put on the program's grid (the answer's `alignment`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alignment {
    /// Log-clock time at which the program starts, s: program time τ of a stamp t is
    /// `(t − delay_s) / rate_ratio`.
    pub delay_s: f64,
    /// Log seconds per program second (1 when no clock drift was found).
    pub rate_ratio: f64,
    /// Samples in the log.
    pub samples: usize,
    /// Log samples inside the diagnosed window (program start to the grid's end).
    pub samples_used: usize,
    /// Log samples before the program's start (used to align, not diagnosed).
    pub samples_before: usize,
    /// Log samples after the grid's end (the program's end plus [`HOLD_S`]).
    pub samples_after: usize,
    /// Stretches of the log without samples.
    pub gaps: Vec<LogGap>,
    /// Instants of the diagnosis grid (`period_s` apart from the program's start).
    pub grid_samples: usize,
    /// Grid instants that carry a log sample (the rest are left out of every fit).
    pub grid_observed: usize,
    /// RMS of |log − stored simulation| over the log's samples at this clock, mm.
    pub residual_rms_mm: f64,
    /// The delay that matches the log to the stored simulation alone, s (log clock): the
    /// first estimate, equal to `delay_s` unless the delay was refined with effects.
    pub delay_stored_s: f64,
    /// Effects (openapi.yaml names) refitted at every delay tried when the delay was refined
    /// ([`refine_delay`]); empty: the delay matches the stored simulation alone.
    pub refined_with: Vec<String>,
    /// RMS of |log − simulation with `refined_with` refitted| over the log's samples inside
    /// the diagnosed window at `delay_s`, mm; `None` when not refined.
    pub residual_effects_rms_mm: Option<f64>,
}

/// A log put on the program's grid: the block (command cut or held to the grid, measured
/// interpolated at the observed instants and equal to the stored simulation elsewhere), the
/// weight of each grid instant (1 observed, 0 not) and the alignment report.
#[derive(Clone, Debug)]
pub struct Aligned {
    /// Command and measured positions per axis on the grid, mm.
    pub block: MotionBlock,
    /// 1 where a log sample lies within half a period of the instant, else 0.
    pub observed: Vec<f64>,
    /// What was found.
    pub alignment: Alignment,
}

/// Checks a log's time stamps at the door: as many as `rows`, finite, strictly increasing.
/// Errors name `field` and the index.
pub fn check_times(field: &str, t: &[f64], rows: usize) -> Result<(), Error> {
    if t.len() != rows {
        return Err(Error::shape(
            field,
            format!(
                "has {} time stamps but measured has {rows} rows: one stamp (s) per row",
                t.len()
            ),
        ));
    }
    if let Some(index) = t.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            field: field.to_string(),
            index,
        });
    }
    if let Some(i) = (1..t.len()).find(|&i| t[i] <= t[i - 1]) {
        return Err(Error::shape(
            &format!("{field}[{i}]"),
            format!(
                "{} s is not after {field}[{}] = {} s: time stamps must strictly increase",
                t[i],
                i - 1,
                t[i - 1]
            ),
        ));
    }
    Ok(())
}

/// Aligns a time-stamped log (`t` s, `log` per axis mm) to the stored simulation of
/// `commanded` (per axis, mm, one row every `period_s` from the program's start) and puts it
/// on the program's grid: [`TimedLog::new`], [`TimedLog::estimate`], [`TimedLog::place`].
/// The clock is matched to the stored simulation only; [`refine_delay`] then moves the delay
/// to where the diagnosed effects fit best.
/// Known bad cases: see [`estimate_clock`] (a pure lag is read as delay); a log sample with a
/// gap on both sides is left out.
pub fn align_block(
    plants: &[AxisPlant],
    commanded: &[Vec<f64>],
    t: &[f64],
    log: &[Vec<f64>],
    period_s: f64,
) -> Result<Aligned, Error> {
    let timed = TimedLog::new(
        plants.to_vec(),
        commanded,
        t.to_vec(),
        log.to_vec(),
        period_s,
    )?;
    timed.place(&timed.estimate()?)
}

/// A time-stamped log beside the program it logs: the command held [`HOLD_S`] past its end,
/// its stored simulation, the stamps and the positions — what every clock is tried against.
#[derive(Clone, Debug)]
pub struct TimedLog {
    /// One plant per axis.
    pub plants: Vec<AxisPlant>,
    /// The command per axis, mm, held [`HOLD_S`] past its end.
    pub extended: Vec<Vec<f64>>,
    /// The stored simulation of `extended` per axis, mm.
    pub reference: Vec<Vec<f64>>,
    /// The log's stamps, s (log clock).
    pub t: Vec<f64>,
    /// The log's positions per axis, mm.
    pub log: Vec<Vec<f64>>,
    /// The program's sample period, s.
    pub period_s: f64,
}

impl TimedLog {
    /// The log (`t` s, `log` per axis mm) of `commanded` (per axis, mm, one row every
    /// `period_s` from the program's start): simulates the command held [`HOLD_S`] past its end
    /// through the plants' linear response. Errors: fewer than 2 command rows.
    pub fn new(
        plants: Vec<AxisPlant>,
        commanded: &[Vec<f64>],
        t: Vec<f64>,
        log: Vec<Vec<f64>>,
        period_s: f64,
    ) -> Result<Self, Error> {
        let n_cmd = commanded.first().map_or(0, Vec::len);
        if n_cmd < 2 {
            return Err(Error::shape("commanded", "needs at least 2 rows"));
        }
        let hold = ((HOLD_S / period_s).ceil() as usize).max(1);
        let extended: Vec<Vec<f64>> = commanded
            .iter()
            .map(|c| {
                let mut e = c.clone();
                e.resize(n_cmd + hold, c[n_cmd - 1]);
                e
            })
            .collect();
        let reference: Vec<Vec<f64>> = plants
            .iter()
            .zip(&extended)
            .map(|(p, c)| p.linear(c))
            .collect();
        Ok(Self {
            plants,
            extended,
            reference,
            t,
            log,
            period_s,
        })
    }

    /// The log's clock against the stored simulation ([`estimate_clock`]).
    pub fn estimate(&self) -> Result<Clock, Error> {
        estimate_clock(&self.reference, self.period_s, &self.t, &self.log)
    }

    /// Program times (s) of the log's stamps at `clock`.
    pub fn program_times(&self, clock: &Clock) -> Vec<f64> {
        self.t.iter().map(|&s| clock.program_time(s)).collect()
    }

    /// Puts the log on the program's grid at `clock`.
    ///
    /// The grid runs from the program's start to the log's last sample (at most the program's
    /// end plus [`HOLD_S`]). Gaps are steps between stamps longer than [`GAP_FACTOR`] times the
    /// median step; a grid instant is observed when a log sample lies within half a period of
    /// it, and takes the log linearly interpolated (or, next to a gap, extrapolated by at most
    /// half a period) from the samples on its side (`grid::resample`).
    /// Reference: the first-order hold of the HTTP contract's command.
    /// Errors ([`Error::Align`]): the log ends before the program starts; more than
    /// [`MAX_GRID_SAMPLES`] grid instants; fewer than [`MIN_OBSERVED`] observed.
    pub fn place(&self, clock: &Clock) -> Result<Aligned, Error> {
        let tau = self.program_times(clock);
        let period_s = self.period_s;
        let last_tau = *tau.last().expect("checked non-empty");
        if last_tau < 0.0 {
            return Err(Error::Align(format!(
                "the log ends {:.3} s before the program starts (delay_s {:.4}): log while the program runs",
                -last_tau, clock.delay_s
            )));
        }
        let n_grid = ((last_tau / period_s + 0.5).floor() as usize + 1).min(self.extended[0].len());
        if n_grid > MAX_GRID_SAMPLES {
            return Err(Error::Align(format!(
                "the log covers {n_grid} periods of {period_s} s from the program's start: at most \
                 {MAX_GRID_SAMPLES} are diagnosed at once; send a shorter log or a longer period_s"
            )));
        }
        let gaps = grid::gaps(&tau);
        let (measured, observed) =
            grid::resample(&self.reference, period_s, &tau, &self.log, &gaps, n_grid);
        let grid_observed = observed.iter().filter(|w| **w > 0.0).count();
        if grid_observed < MIN_OBSERVED {
            return Err(Error::Align(format!(
                "only {grid_observed} instants of the program's grid carry a log sample (delay_s \
                 {:.4}): the log is too short or lies outside the program; at least {MIN_OBSERVED} \
                 are needed",
                clock.delay_s
            )));
        }
        let half = 0.5 * period_s;
        let end = (n_grid - 1) as f64 * period_s + half;
        let samples_before = tau.iter().filter(|&&s| s < -half).count();
        let samples_after = tau.iter().filter(|&&s| s > end).count();
        let t = &self.t;
        let alignment = Alignment {
            delay_s: clock.delay_s,
            rate_ratio: clock.rate_ratio,
            samples: t.len(),
            samples_used: t.len() - samples_before - samples_after,
            samples_before,
            samples_after,
            gaps: gaps
                .iter()
                .enumerate()
                .filter(|(_, g)| **g)
                .map(|(j, _)| LogGap {
                    t_start: t[j],
                    t_end: t[j + 1],
                })
                .collect(),
            grid_samples: n_grid,
            grid_observed,
            residual_rms_mm: clock.residual_rms_mm,
            delay_stored_s: clock.delay_s,
            refined_with: Vec::new(),
            residual_effects_rms_mm: None,
        };
        let commanded = self.extended.iter().map(|c| c[..n_grid].to_vec());
        Ok(Aligned {
            block: MotionBlock {
                commanded: commanded.collect(),
                measured,
            },
            observed,
            alignment,
        })
    }
}

#[cfg(test)]
mod tests;
