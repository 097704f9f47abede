//! ISO 230-2 from a logged positioning run: the command and the laser (or scale) reading,
//! sampled every `period_s`. The service finds what an operator would read off the plot:
//!
//! 1. **Dwells**: runs where the command holds still for at least `min_dwell_s`.
//! 2. **Approach direction** of each dwell: the sign of the last command motion before it, so
//!    a target approached through an overtravel and a reversal (ISO 230-2:2014 §5.3.2, the
//!    standard's linear cycle) counts in the direction of its final approach.
//! 3. **Targets**: dwell positions grouped within `target_tolerance_mm`; a group reached from
//!    one direction only (a turnaround or overtravel point where the program paused, the
//!    start or end position) is not a target and is listed among the ignored dwells.
//! 4. **Settled reading**: the mean of the dwell's tail from the first sample after which the
//!    reading stays inside a band about the tail's median (4 robust σ of the last third of
//!    the dwell, at least `settle_floor_mm`); the settling before it and the motion are
//!    ignored. A dwell whose tail is shorter than three samples did not settle and is ignored.
//!
//! Every reading used and every dwell ignored is reported with its sample range, so the
//! caller can check the choice on the plot. Written here: no crate reads machine-tool
//! positioning logs.

use super::error::Error;
use super::iso230_2::{Axis230_2, PositionTable, evaluate_table};

/// A logged positioning run of one axis.
#[derive(Clone, Debug, PartialEq)]
pub struct PositioningTrace {
    /// Sampling period, s.
    pub period_s: f64,
    /// Commanded position per sample, mm.
    pub commanded_mm: Vec<f64>,
    /// Measured position per sample (laser interferometer or scale), mm.
    pub measured_mm: Vec<f64>,
}

/// How dwells are found and read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceOptions {
    /// Shortest hold of the command that counts as a dwell, s (default 0.1).
    pub min_dwell_s: f64,
    /// Dwell positions closer than this are one target, mm (default 0.001).
    pub target_tolerance_mm: f64,
    /// Narrowest settling band, mm (default 0.00001 = 10 nm, a laser's resolution).
    pub settle_floor_mm: f64,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            min_dwell_s: 0.1,
            target_tolerance_mm: 0.001,
            settle_floor_mm: 1e-5,
        }
    }
}

/// One dwell found in the run.
#[derive(Clone, Debug, PartialEq)]
pub struct Dwell {
    /// First sample of the dwell (the command holds from here).
    pub start: usize,
    /// One past its last sample.
    pub end: usize,
    /// The commanded position held, mm.
    pub commanded_mm: f64,
    /// Direction of the final approach: `Some(true)` positive, `Some(false)` negative,
    /// `None` when the command never moved before it.
    pub forward: Option<bool>,
    /// First sample of the settled tail, if it settled.
    pub settled_start: Option<usize>,
    /// Mean measured position over the settled tail, mm.
    pub reading_mm: Option<f64>,
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
    /// The dwell's samples `[start, end)`.
    pub dwell: [usize; 2],
    /// The settled samples averaged, `[start, end)`.
    pub settled: [usize; 2],
    /// The reading, mm.
    pub reading_mm: f64,
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
    /// Dwells not used: `(start, end, reason)`.
    pub ignored: Vec<(usize, usize, String)>,
}

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
    positive("settle_floor_mm", opts.settle_floor_mm, "a distance > 0 mm")
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let k = v.len() / 2;
    if v.len() % 2 == 1 {
        v[k]
    } else {
        0.5 * (v[k - 1] + v[k])
    }
}

/// The first sample of the settled tail of `y` (see the module docs), or `None`.
fn settled_from(y: &[f64], floor_mm: f64) -> Option<usize> {
    let tail = &y[y.len() - (y.len() / 3).max(1)..];
    let centre = median(&mut tail.to_vec());
    let mut abs: Vec<f64> = tail.iter().map(|v| (v - centre).abs()).collect();
    let band = (4.0 * 1.4826 * median(&mut abs)).max(floor_mm);
    let last_out = y.iter().rposition(|v| (v - centre).abs() > band);
    let from = last_out.map_or(0, |k| k + 1);
    (y.len() - from >= 3).then_some(from)
}

/// Finds the dwells of a run (see the module docs).
pub fn find_dwells(trace: &PositioningTrace, opts: &TraceOptions) -> Vec<Dwell> {
    let c = &trace.commanded_mm;
    let min_len = ((opts.min_dwell_s / trace.period_s).ceil() as usize).max(3);
    let still = |k: usize| (c[k] - c[k - 1]).abs() <= 1e-12 * (1.0 + c[k].abs());
    let mut dwells = Vec::new();
    let mut last_dir: Option<bool> = None;
    let mut k = 1;
    let mut start = 0;
    while k <= c.len() {
        if k < c.len() && still(k) {
            k += 1;
            continue;
        }
        // [start, k) holds the command still.
        if k - start >= min_len {
            let y = &trace.measured_mm[start..k];
            let settled = settled_from(y, opts.settle_floor_mm).map(|s| start + s);
            let reading = settled.map(|s| {
                let tail = &trace.measured_mm[s..k];
                tail.iter().sum::<f64>() / tail.len() as f64
            });
            dwells.push(Dwell {
                start,
                end: k,
                commanded_mm: c[start],
                forward: last_dir,
                settled_start: settled,
                reading_mm: reading,
            });
        }
        if k < c.len() {
            last_dir = Some(c[k] > c[k - 1]);
        }
        start = k;
        k += 1;
    }
    dwells
}

/// Evaluates a logged positioning run by ISO 230-2:2014 (see the module docs for how the
/// targets, directions and settled readings are found, and [`evaluate_table`] for the
/// figures). Errors: mismatched or non-finite arrays, bad options, and the table's own
/// refusals (fewer than 2 targets approached from both sides, fewer than 2 cycles).
///
/// Reference: ISO 230-2:2014 §5.3.2 (linear cycle, overtravel) and §3, §7.
///
/// Known bad cases: a command that creeps (never holds still) has no dwells; a reading
/// that drifts through the whole dwell never settles inside the band and is ignored.
pub fn evaluate_trace(
    trace: &PositioningTrace,
    opts: &TraceOptions,
) -> Result<TraceEvaluation, Error> {
    check(trace, opts)?;
    let dwells = find_dwells(trace, opts);
    let mut ignored = Vec::new();
    // Groups of dwell positions: (position, indices of the dwells in it).
    let mut groups: Vec<(f64, Vec<usize>)> = Vec::new();
    for (i, d) in dwells.iter().enumerate() {
        if d.forward.is_none() {
            ignored.push((
                d.start,
                d.end,
                "no command motion before it (the start position)".into(),
            ));
            continue;
        }
        if d.reading_mm.is_none() {
            ignored.push((
                d.start,
                d.end,
                "the reading did not settle within the dwell".into(),
            ));
            continue;
        }
        match groups
            .iter_mut()
            .find(|(p, _)| (p - d.commanded_mm).abs() <= opts.target_tolerance_mm)
        {
            Some((_, members)) => members.push(i),
            None => groups.push((d.commanded_mm, vec![i])),
        }
    }
    groups.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut table = PositionTable {
        targets_mm: Vec::new(),
        forward_mm: Vec::new(),
        backward_mm: Vec::new(),
    };
    let mut used = Vec::new();
    let dwells = &dwells;
    for (position, members) in groups {
        let members = &members;
        let dir = |fwd: bool| {
            members
                .iter()
                .filter(move |&&i| dwells[i].forward == Some(fwd))
        };
        if dir(true).next().is_none() || dir(false).next().is_none() {
            let from = if dir(true).next().is_some() {
                "positive"
            } else {
                "negative"
            };
            for &i in members {
                ignored.push((
                    dwells[i].start,
                    dwells[i].end,
                    format!(
                        "{position} mm is approached only from the {from} direction: a turnaround or end point, not a target"
                    ),
                ));
            }
            continue;
        }
        table.targets_mm.push(position);
        for fwd in [true, false] {
            let mut row = Vec::new();
            for (cycle, &i) in dir(fwd).enumerate() {
                let d = &dwells[i];
                let reading = d.reading_mm.unwrap_or(f64::NAN);
                row.push(reading);
                used.push(TraceReading {
                    target_mm: position,
                    forward: fwd,
                    cycle,
                    dwell: [d.start, d.end],
                    settled: [d.settled_start.unwrap_or(d.start), d.end],
                    reading_mm: reading,
                });
            }
            if fwd {
                table.forward_mm.push(row);
            } else {
                table.backward_mm.push(row);
            }
        }
    }
    used.sort_by_key(|r| r.dwell[0]);
    ignored.sort_by_key(|r| r.0);
    let axis = evaluate_table(&table)?;
    Ok(TraceEvaluation {
        axis,
        table,
        used,
        ignored,
    })
}

#[cfg(test)]
mod tests;
