//! Reading a logged positioning run into the ISO 230-2 table: the types, the commanded
//! approaches and the evaluation (the steps are in the module docs of `metrology::trace`).

use super::matching::{
    Matched, Visit, device_offset, match_stops, match_tolerance, visits_by_position,
};
use super::settle::{self, merge_stops, settled_runs};
use crate::metrology::error::Error;
use crate::metrology::iso230_2::{Axis230_2, PositionTable, evaluate_table};

/// A logged positioning run of one axis.
#[derive(Clone, Debug, PartialEq)]
pub struct PositioningTrace {
    /// Sampling period, s.
    pub period_s: f64,
    /// Commanded position per sample, mm.
    pub commanded_mm: Vec<f64>,
    /// Measured position per sample (laser interferometer or scale), mm. Its samples need not
    /// be simultaneous with the command's (the device may have its own clock).
    pub measured_mm: Vec<f64>,
}

/// How approaches are found and readings taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceOptions {
    /// Shortest hold of the command that counts as a commanded approach, s (default 0.1).
    pub min_dwell_s: f64,
    /// Commanded positions closer than this are one, mm (default 0.001).
    pub target_tolerance_mm: f64,
    /// The measured position has settled while it moves slower than this, mm/s (default 0.01).
    pub settle_speed_mm_s: f64,
    /// ... for at least this long (the window the speed is judged over), s (default 0.3).
    pub min_settled_s: f64,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            min_dwell_s: 0.1,
            target_tolerance_mm: 0.001,
            settle_speed_mm_s: 0.01,
            min_settled_s: 0.3,
        }
    }
}

/// A reading the evaluation used.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceReading {
    /// Target position, mm.
    pub target_mm: f64,
    /// Approached in the positive direction.
    pub forward: bool,
    /// Cycle number in that direction at that target (0-based, in time order).
    pub cycle: usize,
    /// The command's hold this reading answers, `[start, end)` in command samples.
    pub command: [usize; 2],
    /// The settled samples averaged: the stop's settled end, `[start, end)` in measured
    /// samples (settled ones only, when noise split the stop).
    pub settled: [usize; 2],
    /// The reading (mean measured position over the stop's settled end), mm.
    pub reading_mm: f64,
}

/// The settling rule used and what the matching found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settling {
    /// Speed threshold, mm/s.
    pub settle_speed_mm_s: f64,
    /// Minimum settled time, s.
    pub min_settled_s: f64,
    /// The speed window actually used, s (2h + 1 samples); a reading averages the last such
    /// window of its stop.
    pub window_s: f64,
    /// How far a stop may sit from a commanded position, mm.
    pub match_tolerance_mm: f64,
    /// Median of reading − target over the readings used, mm: the measuring device's offset
    /// plus the axis' mean deviation (it changes no figure).
    pub measured_offset_mm: f64,
}

/// The evaluation of a logged run: the ISO 230-2 figures and what was read.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceEvaluation {
    /// The axis figures from the table below.
    pub axis: Axis230_2,
    /// The table the readings make.
    pub table: PositionTable,
    /// Every reading used, in time order.
    pub used: Vec<TraceReading>,
    /// Settled stops not used: `(start, end, reason)` in measured samples.
    pub ignored: Vec<(usize, usize, String)>,
    /// The settling rule and the matching.
    pub settling: Settling,
}

/// Most targets a logged run is read into (the table's checks grow with their square).
pub const MAX_TARGETS: usize = 10_000;

fn check(trace: &PositioningTrace, opts: &TraceOptions) -> Result<(), Error> {
    let n = trace.commanded_mm.len();
    if trace.measured_mm.len() != n {
        return Err(Error::LengthMismatch {
            field: "measured".into(),
            got: trace.measured_mm.len(),
            expected: n,
            why: "one measured position per commanded sample",
        });
    }
    for (field, xs) in [
        ("commanded", &trace.commanded_mm),
        ("measured", &trace.measured_mm),
    ] {
        if let Some(index) = xs.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite {
                field: field.into(),
                index,
            });
        }
    }
    let positive = |field, value: f64, reason| {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(Error::Invalid {
                field,
                value,
                reason,
            })
        }
    };
    positive("period_s", trace.period_s, "a sampling period > 0 s")?;
    positive("min_dwell_s", opts.min_dwell_s, "a duration > 0 s")?;
    positive(
        "target_tolerance_mm",
        opts.target_tolerance_mm,
        "a distance > 0 mm",
    )?;
    positive(
        "settle_speed_mm_s",
        opts.settle_speed_mm_s,
        "a speed > 0 mm/s",
    )?;
    positive("min_settled_s", opts.min_settled_s, "a duration > 0 s")
}

/// The commanded approaches of a run (see the module docs) and the sorted distinct commanded
/// positions their `position` indexes.
pub fn find_visits(trace: &PositioningTrace, opts: &TraceOptions) -> (Vec<Visit>, Vec<f64>) {
    let c = &trace.commanded_mm;
    let min_len = (opts.min_dwell_s / trace.period_s).ceil().max(2.0);
    let still = |k: usize| (c[k] - c[k - 1]).abs() <= 1e-12 * (1.0 + c[k].abs());
    let mut visits = Vec::new();
    let mut last_dir: Option<bool> = None;
    let mut start = 0;
    for k in 1..=c.len() {
        if k % 65_536 == 0 {
            crate::numeric::stop::check();
        }
        if k < c.len() && still(k) {
            continue;
        }
        if (k - start) as f64 >= min_len {
            visits.push(Visit {
                start,
                end: k,
                commanded_mm: c[start],
                position: 0,
                forward: last_dir,
            });
        }
        if k < c.len() {
            last_dir = Some(c[k] > c[k - 1]);
        }
        start = k;
    }
    let mut held: Vec<f64> = visits.iter().map(|v| v.commanded_mm).collect();
    held.sort_by(f64::total_cmp);
    let mut positions: Vec<f64> = Vec::new();
    for p in held {
        if positions
            .last()
            .is_none_or(|q| p - q > opts.target_tolerance_mm)
        {
            positions.push(p);
        }
    }
    for v in &mut visits {
        let i = positions.partition_point(|&p| p <= v.commanded_mm + opts.target_tolerance_mm);
        v.position = i - 1;
    }
    (visits, positions)
}

/// Evaluates a logged positioning run by ISO 230-2:2014: readings at the settled end of each
/// stop of the measured position, matched to the command's approaches (see the module docs),
/// then [`evaluate_table`]. Errors: mismatched or non-finite arrays, bad options
/// ([`Error::Invalid`]), a target with fewer readings than cycles in a direction
/// ([`Error::MissingReadings`]), and the table's own refusals (fewer than 2 targets).
///
/// Formula: reading = mean of the measured position over the stop's last speed window of
/// settled samples (2h + 1, about `min_settled_s`; [`super::SettledRun::settled_end`]); the
/// figures are [`evaluate_table`]'s.
///
/// Reference: ISO 230-2:2014 §5.3.2 (linear cycle, overrun) and §3, §7.
///
/// Known bad cases: a command that creeps (never holds still) has no approaches; an axis that
/// never moves slower than `settle_speed_mm_s` for `min_settled_s` at a target is refused;
/// a measured series counting against the command (a laser set up reversed) matches nothing.
pub fn evaluate_trace(
    trace: &PositioningTrace,
    opts: &TraceOptions,
) -> Result<TraceEvaluation, Error> {
    check(trace, opts)?;
    let (visits, positions) = find_visits(trace, opts);
    let y = &trace.measured_mm;
    let h = settle::half_window(trace.period_s, opts.min_settled_s, y.len());
    let runs = merge_stops(
        y,
        settled_runs(
            y,
            trace.period_s,
            opts.settle_speed_mm_s,
            opts.min_settled_s,
        ),
    );
    let stops: Vec<f64> = runs.iter().map(|r| r.mean_mm).collect();
    let tol = match_tolerance(&positions);
    let offset = device_offset(&stops, &positions, tol);
    let by_position = visits_by_position(&visits, positions.len());
    let matched = match_stops(&stops, &by_position, &positions, offset, tol);
    // Approaches per position and direction (the cycles), and which are targets.
    let mut count = vec![[0_usize; 2]; positions.len()];
    for v in &visits {
        if let Some(fwd) = v.forward {
            count[v.position][usize::from(!fwd)] += 1;
        }
    }
    let is_target = |g: usize| count[g][0] >= 2 && count[g][1] >= 2;
    let mut ignored = Vec::new();
    let mut answered = vec![None; visits.len()];
    for (run, m) in runs.iter().zip(matched) {
        let why = match m {
            Matched::Unused(why) => why,
            Matched::Visit(v) => {
                let visit = &visits[v];
                let g = visit.position;
                match visit.forward {
                    None => "the start position: no command motion before it".into(),
                    Some(_) if !is_target(g) => format!(
                        "{} mm is approached {} times in the positive and {} in the negative \
                         direction: a start, end or turnaround point, not a target",
                        positions[g], count[g][0], count[g][1]
                    ),
                    Some(_) => {
                        answered[v] = Some(run);
                        continue;
                    }
                }
            }
        };
        ignored.push((run.start, run.end, why));
    }
    let mut table = PositionTable {
        targets_mm: Vec::new(),
        forward_mm: Vec::new(),
        backward_mm: Vec::new(),
    };
    let mut used = Vec::new();
    for (g, &position) in positions.iter().enumerate() {
        if !is_target(g) {
            continue;
        }
        table.targets_mm.push(position);
        if table.targets_mm.len() > MAX_TARGETS {
            return Err(Error::Invalid {
                field: "commanded",
                value: positions.len() as f64,
                reason: "a logged run of at most 10000 targets (distinct commanded positions \
                         approached twice from each side); send one axis' ISO 230-2 run",
            });
        }
        for fwd in [true, false] {
            let approaches = by_position[g]
                .iter()
                .map(|&v| (v, &visits[v]))
                .filter(|(_, v)| v.forward == Some(fwd));
            let mut row = Vec::new();
            let mut first_missing = None;
            for (v, visit) in approaches {
                match answered[v] {
                    Some(run) => {
                        let (first, reading_mm) = run.settled_end(y, 2 * h + 1);
                        used.push(TraceReading {
                            target_mm: position,
                            forward: fwd,
                            cycle: row.len(),
                            command: [visit.start, visit.end],
                            settled: [first, run.end],
                            reading_mm,
                        });
                        row.push(reading_mm);
                    }
                    None => {
                        first_missing.get_or_insert(visit.start);
                    }
                }
            }
            if let Some(command_sample) = first_missing {
                return Err(Error::MissingReadings {
                    target_mm: position,
                    direction: if fwd { "forward" } else { "backward" },
                    got: row.len(),
                    expected: count[g][usize::from(!fwd)],
                    command_sample,
                    settle_speed_mm_s: opts.settle_speed_mm_s,
                    min_settled_s: opts.min_settled_s,
                });
            }
            if fwd {
                table.forward_mm.push(row);
            } else {
                table.backward_mm.push(row);
            }
        }
    }
    used.sort_by_key(|r| r.settled[0]);
    let axis = evaluate_table(&table)?;
    let mut offsets: Vec<f64> = used.iter().map(|r| r.reading_mm - r.target_mm).collect();
    offsets.sort_by(f64::total_cmp);
    Ok(TraceEvaluation {
        axis,
        table,
        used,
        ignored,
        settling: Settling {
            settle_speed_mm_s: opts.settle_speed_mm_s,
            min_settled_s: opts.min_settled_s,
            window_s: (2 * h + 1) as f64 * trace.period_s,
            match_tolerance_mm: tol,
            measured_offset_mm: offsets.get(offsets.len() / 2).copied().unwrap_or(0.0),
        },
    })
}
