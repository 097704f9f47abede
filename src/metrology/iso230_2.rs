//! ISO 230-2:2014 positioning accuracy and repeatability of a linear (or rotary) axis, from the
//! table of measured positions per target, approach direction and cycle.
//!
//! Written here because the figures are a handful of maxima and minima whose definitions
//! published calculators get wrong: several take the axis repeatability as
//! `max(R↑, R↓)` instead of the bidirectional `R = max_i R_i` with
//! `R_i = max(2s_i↑ + 2s_i↓ + |B_i|, R_i↑, R_i↓)`, or the systematic error E from one direction
//! only. The tests (`iso230_2/tests.rs`) pin every definition with hand-computed tables.
//!
//! Reference: ISO 230-2:2014 §3 (definitions 3.3 to 3.24) and §7 (evaluation); cited as
//! "ISO 230-2:2014 §3.n". Notation: ↑ = approach in the positive direction (`fwd`), ↓ = in
//! the negative direction (`bwd`); i = target, j = cycle.

use super::error::Error;

/// Fewest targets the standard asks for (ISO 230-2:2014 §5.2: at least five per metre and
/// at least five in all); fewer are evaluated with a warning.
pub const ISO_MIN_TARGETS: usize = 5;
/// Cycles the standard's normal test runs (ISO 230-2:2014 §5.3.2: five approaches in each
/// direction); fewer are evaluated with a warning.
pub const ISO_CYCLES: usize = 5;

/// Measured positions of an axis, mm (or degrees for a rotary axis).
#[derive(Clone, Debug, PartialEq)]
pub struct PositionTable {
    /// Target positions P_i, mm.
    pub targets_mm: Vec<f64>,
    /// Measured positions P_ij↑ approached in the positive direction: one row per target,
    /// one entry per cycle, mm.
    pub forward_mm: Vec<Vec<f64>>,
    /// Measured positions P_ij↓ approached in the negative direction, mm.
    pub backward_mm: Vec<Vec<f64>>,
}

/// The per-target figures (ISO 230-2:2014 §3.8 to §3.18), mm.
#[derive(Clone, Debug, PartialEq)]
pub struct Target230_2 {
    /// Target position P_i, mm.
    pub target_mm: f64,
    /// Cycles approached in the positive direction.
    pub n_fwd: usize,
    /// Cycles approached in the negative direction.
    pub n_bwd: usize,
    /// Mean unidirectional positional deviation x̄_i↑ = (1/n) Σ_j (P_ij↑ − P_i) (§3.9), mm.
    pub mean_fwd: f64,
    /// Mean unidirectional positional deviation x̄_i↓ (§3.9), mm.
    pub mean_bwd: f64,
    /// Mean bidirectional positional deviation x̄_i = (x̄_i↑ + x̄_i↓)/2 (§3.10), mm.
    pub mean: f64,
    /// Estimator of the unidirectional standard uncertainty s_i↑ (n − 1 in the
    /// denominator, §3.13), mm.
    pub s_fwd: f64,
    /// s_i↓ (§3.13), mm.
    pub s_bwd: f64,
    /// Reversal value B_i = x̄_i↑ − x̄_i↓ (§3.11), mm, signed.
    pub reversal: f64,
    /// Unidirectional repeatability R_i↑ = 4 s_i↑ (§3.15), mm.
    pub r_fwd: f64,
    /// R_i↓ = 4 s_i↓ (§3.15), mm.
    pub r_bwd: f64,
    /// Bidirectional repeatability R_i = max(2s_i↑ + 2s_i↓ + |B_i|, R_i↑, R_i↓) (§3.16), mm.
    pub r: f64,
}

/// The axis figures of ISO 230-2:2014 §3.19 to §3.24, mm, with the per-target table.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis230_2 {
    /// Bidirectional accuracy A = max(x̄_i↑ + 2s_i↑, x̄_i↓ + 2s_i↓) − min(x̄_i↑ − 2s_i↑,
    /// x̄_i↓ − 2s_i↓) over both directions (§3.24), mm.
    pub a: f64,
    /// Unidirectional accuracy A↑ = max(x̄_i↑ + 2s_i↑) − min(x̄_i↑ − 2s_i↑) (§3.23), mm.
    pub a_fwd: f64,
    /// A↓ (§3.23), mm.
    pub a_bwd: f64,
    /// Bidirectional systematic positioning error E = max(x̄_i↑, x̄_i↓) − min(x̄_i↑, x̄_i↓)
    /// over both directions (§3.21), mm.
    pub e: f64,
    /// Unidirectional systematic positioning error E↑ = max x̄_i↑ − min x̄_i↑ (§3.20), mm.
    pub e_fwd: f64,
    /// E↓ (§3.20), mm.
    pub e_bwd: f64,
    /// Mean bidirectional positional deviation of the axis M = max x̄_i − min x̄_i (§3.22), mm.
    pub m: f64,
    /// Bidirectional repeatability of the axis R = max R_i (§3.19), mm; not max(R↑, R↓).
    pub r: f64,
    /// Unidirectional repeatability R↑ = max R_i↑ (§3.18), mm.
    pub r_fwd: f64,
    /// R↓ = max R_i↓ (§3.18), mm.
    pub r_bwd: f64,
    /// Reversal value of the axis B = max |B_i| (§3.12), mm.
    pub b: f64,
    /// Mean reversal value B̄ = (1/m) Σ B_i, signed (§3.12), mm.
    pub b_avg: f64,
    /// The per-target table, in the order the targets were sent.
    pub targets: Vec<Target230_2>,
    /// Departures from the standard's test conditions that were evaluated anyway (fewer than
    /// five targets or cycles, unequal cycles).
    pub warnings: Vec<String>,
}

fn check_finite(field: &str, xs: &[f64]) -> Result<(), Error> {
    match xs.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(index) => Err(Error::NonFinite {
            field: field.to_string(),
            index,
        }),
    }
}

/// Mean and the estimator s with n − 1 in the denominator (ISO 230-2:2014 §3.13).
fn mean_and_s(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let ss: f64 = xs.iter().map(|x| (x - mean) * (x - mean)).sum();
    (mean, (ss / (n - 1.0)).sqrt())
}

impl PositionTable {
    /// Checks the table: finite numbers, one row per target in each direction, at least two
    /// targets and two cycles per direction (s needs n − 1 ≥ 1), no repeated target.
    /// Returns the warnings for departures the figures survive (fewer than
    /// [`ISO_MIN_TARGETS`] targets or [`ISO_CYCLES`] cycles, unequal cycles).
    pub fn check(&self) -> Result<Vec<String>, Error> {
        let m = self.targets_mm.len();
        check_finite("targets", &self.targets_mm)?;
        if m < 2 {
            return Err(Error::TooFew {
                field: "targets".into(),
                got: m,
                need: "the axis figures need at least 2 targets (ISO 230-2 asks for 5 or more)",
            });
        }
        for (name, rows) in [
            ("forward", &self.forward_mm),
            ("backward", &self.backward_mm),
        ] {
            if rows.len() != m {
                return Err(Error::LengthMismatch {
                    field: name.into(),
                    got: rows.len(),
                    expected: m,
                    why: "one row of measured positions per target",
                });
            }
            for (i, row) in rows.iter().enumerate() {
                check_finite(&format!("{name}[{i}]"), row)?;
                if row.len() < 2 {
                    return Err(Error::TooFew {
                        field: format!("{name}[{i}] cycles"),
                        got: row.len(),
                        need: "s needs at least 2 cycles per target and direction (ISO 230-2 runs 5)",
                    });
                }
            }
        }
        for i in 0..m {
            for j in 0..i {
                if self.targets_mm[i] == self.targets_mm[j] {
                    return Err(Error::DuplicateTarget {
                        first: j,
                        second: i,
                        value: self.targets_mm[i],
                    });
                }
            }
        }
        let mut warnings = Vec::new();
        if m < ISO_MIN_TARGETS {
            warnings.push(format!(
                "{m} targets: ISO 230-2:2014 asks for at least {ISO_MIN_TARGETS}; the figures are not conformant"
            ));
        }
        let cycles = self
            .forward_mm
            .iter()
            .chain(&self.backward_mm)
            .map(Vec::len);
        let (lo, hi) = cycles.fold((usize::MAX, 0), |(lo, hi), n| (lo.min(n), hi.max(n)));
        if lo < ISO_CYCLES {
            warnings.push(format!(
                "{lo} cycles at some target: ISO 230-2:2014 runs {ISO_CYCLES} in each direction; \
                 s (and so R and A) is less certain"
            ));
        }
        if lo != hi {
            warnings.push(format!(
                "unequal cycles ({lo} to {hi}) across targets and directions: each target's s uses its own n"
            ));
        }
        Ok(warnings)
    }
}

/// Evaluates an axis by ISO 230-2:2014: the per-target table and the axis figures A, E, M,
/// R and B, each overall (bidirectional) and per direction. Units as the table (mm).
///
/// Formula (ISO 230-2:2014 §3.8 to §3.24): deviation x_ij = P_ij − P_i (measured − target);
/// x̄_i↑ = mean_j x_ij↑; s_i↑ = sqrt(Σ_j (x_ij↑ − x̄_i↑)² / (n − 1)); B_i = x̄_i↑ − x̄_i↓;
/// R_i = max(2s_i↑ + 2s_i↓ + |B_i|, 4s_i↑, 4s_i↓); R = max_i R_i; E = max over both
/// directions of x̄ − min over both; A = max(x̄ + 2s) − min(x̄ − 2s) over both directions;
/// M = max x̄_i − min x̄_i; B = max |B_i|; B̄ = mean B_i.
///
/// Reference: ISO 230-2:2014 §3 and §7.
///
/// Known bad cases: none numerically (a few sums); the figures mean what the standard says
/// only for a test run as the standard says (warnings name the departures).
pub fn evaluate_table(table: &PositionTable) -> Result<Axis230_2, Error> {
    let warnings = table.check()?;
    let targets: Vec<Target230_2> = table
        .targets_mm
        .iter()
        .zip(table.forward_mm.iter().zip(&table.backward_mm))
        .map(|(&p, (fwd, bwd))| {
            let dev = |row: &[f64]| row.iter().map(|x| x - p).collect::<Vec<_>>();
            let (mean_fwd, s_fwd) = mean_and_s(&dev(fwd));
            let (mean_bwd, s_bwd) = mean_and_s(&dev(bwd));
            let reversal = mean_fwd - mean_bwd;
            let (r_fwd, r_bwd) = (4.0 * s_fwd, 4.0 * s_bwd);
            Target230_2 {
                target_mm: p,
                n_fwd: fwd.len(),
                n_bwd: bwd.len(),
                mean_fwd,
                mean_bwd,
                mean: 0.5 * (mean_fwd + mean_bwd),
                s_fwd,
                s_bwd,
                reversal,
                r_fwd,
                r_bwd,
                r: (2.0 * s_fwd + 2.0 * s_bwd + reversal.abs())
                    .max(r_fwd)
                    .max(r_bwd),
            }
        })
        .collect();
    let max =
        |f: &dyn Fn(&Target230_2) -> f64| targets.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
    let min = |f: &dyn Fn(&Target230_2) -> f64| targets.iter().map(f).fold(f64::INFINITY, f64::min);
    let e_fwd = max(&|t| t.mean_fwd) - min(&|t| t.mean_fwd);
    let e_bwd = max(&|t| t.mean_bwd) - min(&|t| t.mean_bwd);
    let e = max(&|t| t.mean_fwd.max(t.mean_bwd)) - min(&|t| t.mean_fwd.min(t.mean_bwd));
    let a_fwd = max(&|t| t.mean_fwd + 2.0 * t.s_fwd) - min(&|t| t.mean_fwd - 2.0 * t.s_fwd);
    let a_bwd = max(&|t| t.mean_bwd + 2.0 * t.s_bwd) - min(&|t| t.mean_bwd - 2.0 * t.s_bwd);
    let a = max(&|t| (t.mean_fwd + 2.0 * t.s_fwd).max(t.mean_bwd + 2.0 * t.s_bwd))
        - min(&|t| (t.mean_fwd - 2.0 * t.s_fwd).min(t.mean_bwd - 2.0 * t.s_bwd));
    let m = max(&|t| t.mean) - min(&|t| t.mean);
    Ok(Axis230_2 {
        a,
        a_fwd,
        a_bwd,
        e,
        e_fwd,
        e_bwd,
        m,
        r: max(&|t| t.r),
        r_fwd: max(&|t| t.r_fwd),
        r_bwd: max(&|t| t.r_bwd),
        b: max(&|t| t.reversal.abs()),
        b_avg: targets.iter().map(|t| t.reversal).sum::<f64>() / targets.len() as f64,
        targets,
        warnings,
    })
}

#[cfg(test)]
pub(crate) mod tests;
