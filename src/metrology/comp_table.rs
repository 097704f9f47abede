//! The pitch-error compensation table of an axis from its ISO 230-2 run: the step after the
//! evaluation, what a controller loads so that the axis lands on its targets.
//!
//! The table is the systematic part of the run: per position a correction for each approach
//! direction, either the negated mean deviations at the run's targets ([`TableSource::Mean`])
//! or the negated fitted model ([`crate::metrology::comp_model`]) sampled on a spacing within
//! the run's range ([`TableSource::Model`]).
//!
//! **Sign.** A correction is what the controller adds to the commanded position:
//! `correction = −(mean deviation)`, deviation = measured − target (ISO 230-2:2014 §3.8). An
//! axis that stops 5 µm past its target gets −0.005 mm. This is LinuxCNC's convention for a
//! `COMP_FILE_TYPE = 1` file: its motion controller adds the interpolated trim of the
//! direction of motion to the joint's commanded position (`motor_pos_cmd = pos_cmd +
//! backlash_filt`, `src/emc/motion/control.c`) and a type-0 file's actual positions become
//! trims as `nominal − actual` (`usrmotLoadComp`, `src/emc/motion/usrmotintf.cc`).
//!
//! **Reference.** A pitch-error table corrects the lead of the axis, not where its zero is:
//! the axis' zero is set by homing, and a measuring device is zeroed wherever it was set up
//! (a laser zeroed at the start point reads every position 37 mm off). So every table is
//! referenced to a stated target ([`Reference`]): its forward correction is 0 by definition
//! and every other correction is relative to it, c = −(x̄ − x̄_ref↑). This is how controllers
//! define their tables (a Fanuc pitch-error table has a compensation point at the reference
//! position, parameter 3620, whose value the others are counted from; LinuxCNC's trims are
//! added to a homed joint, so a constant trim moves the whole axis). The device's zero never
//! enters: a constant in every reading cancels in x̄ − x̄_ref↑. A correction larger than
//! [`MAX_CORRECTION_MM`] is refused ([`Error::CorrectionTooLarge`]).
//!
//! **Applying it** ([`CompTable::correction_mm`], [`CompTable::apply`]) follows LinuxCNC's
//! `compute_screw_comp`: linear interpolation between neighbouring positions, the end values
//! held beyond the ends, the forward column while the command moves up and the backward column
//! while it moves down (at rest the last direction's, i.e. the approach direction's).

use super::comp_model::{Cyclic, PitchModel, fit_model};
pub use super::comp_reference::Reference;
use super::comp_reference::reference_target;
use super::error::Error;
use super::iso230_2::{Axis230_2, PositionTable, evaluate_table};

/// The sign convention as one sentence, for file headers and answers.
pub const SIGN_CONVENTION: &str = "correction = what the controller adds to the commanded \
    position = -(mean deviation - the reference target's forward mean deviation), deviation = \
    measured - target (ISO 230-2); forward = approach or motion in the positive direction, \
    backward = in the negative direction";

/// Most positions a table may have (any format; LinuxCNC loads fewer, see
/// [`crate::metrology::comp_format::LINUXCNC_MAX_TRIPLETS`]).
pub const MAX_TABLE_POSITIONS: usize = 10_001;

/// Finest spacing of a model table, mm (the files print positions to 1 nm; 1 µm keeps
/// neighbouring positions apart by far more than that).
pub const MIN_SPACING_MM: f64 = 0.001;

/// Largest correction a pitch-error table may carry, mm.
///
/// A pitch-error table corrects the lead errors of a screw, rack or scale: micrometres to a
/// few tens of micrometres over a metre (ISO 230-2 E of a machine-tool axis is typically
/// 5–50 µm). A correction of a millimetre is no lead error: it means an offset (readings
/// referenced to another zero), readings of another axis, or other units (inch readings of a
/// mm axis), and loading it would move the axis by that much. 1 mm is twenty times the worst
/// lead error of a metre of ground screw and a thousandth of a typical axis.
pub const MAX_CORRECTION_MM: f64 = 1.0;

/// What the table is built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TableSource {
    /// The mean deviations x̄_i↑, x̄_i↓ at the run's targets, negated.
    Mean,
    /// The fitted model, negated, on `spacing_mm` (default [`default_spacing_mm`]) from the
    /// first to the last target.
    Model {
        /// The cyclic term of the model.
        cyclic: Cyclic,
        /// Spacing of the table's positions, mm.
        spacing_mm: Option<f64>,
    },
}

/// A compensation table: ascending positions and, per position, the correction the controller
/// adds to the command in each direction. Lengths in mm.
#[derive(Clone, Debug, PartialEq)]
pub struct CompTable {
    /// Nominal (commanded) positions, strictly ascending, mm.
    pub positions_mm: Vec<f64>,
    /// Correction while approaching / moving in the positive direction, mm.
    pub forward_mm: Vec<f64>,
    /// Correction while approaching / moving in the negative direction, mm.
    pub backward_mm: Vec<f64>,
    /// The fitted model, for a model table.
    pub model: Option<PitchModel>,
    /// Spacing used, mm, for a model table (the last step may be shorter: the table ends at the
    /// run's last target).
    pub spacing_mm: Option<f64>,
    /// The target the corrections are counted from (its forward correction is 0).
    pub reference: Reference,
}

/// The default spacing of a model table for a run over `range_mm`: the smallest of 1, 2, 5 ×
/// 10^k mm that gives at most 100 steps (800 mm → 10 mm, 2 m → 20 mm).
pub fn default_spacing_mm(range_mm: f64) -> f64 {
    let want = (range_mm / 100.0).max(MIN_SPACING_MM);
    let decade = 10f64.powf(want.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * decade)
        .find(|s| *s >= want * (1.0 - 1e-12))
        .unwrap_or(10.0 * decade)
}

/// Positions from `lo` to `hi` (both included) every `spacing_mm`; the last step is shorter
/// when the range is not a whole number of steps, and a step shorter than 1 % of the
/// spacing is merged into the one before it.
fn grid(lo: f64, hi: f64, spacing_mm: f64) -> Result<Vec<f64>, Error> {
    if !(spacing_mm.is_finite() && spacing_mm >= MIN_SPACING_MM) {
        return Err(Error::Invalid {
            field: "spacing_mm",
            value: spacing_mm,
            reason: "the spacing of the table is a number of mm, at least 0.001",
        });
    }
    let steps = ((hi - lo) / spacing_mm).ceil();
    if steps + 1.0 > MAX_TABLE_POSITIONS as f64 {
        return Err(Error::Unresolvable {
            field: "spacing_mm",
            reason: format!(
                "{spacing_mm} mm over the run's {} mm gives {} positions; a table has at most \
                 {MAX_TABLE_POSITIONS}: use spacing_mm of at least {}",
                hi - lo,
                steps + 1.0,
                (hi - lo) / (MAX_TABLE_POSITIONS - 1) as f64
            ),
        });
    }
    let mut out = vec![lo];
    let mut k = 1.0;
    while lo + k * spacing_mm < hi - 0.01 * spacing_mm {
        out.push(lo + k * spacing_mm);
        k += 1.0;
    }
    out.push(hi);
    Ok(out)
}

/// Refuses a table with a correction beyond [`MAX_CORRECTION_MM`], naming the largest.
fn check_limit(table: &CompTable) -> Result<(), Error> {
    let mut worst: Option<(f64, &'static str, f64)> = None;
    for (k, &p) in table.positions_mm.iter().enumerate() {
        for (dir, c) in [
            ("forward", table.forward_mm[k]),
            ("backward", table.backward_mm[k]),
        ] {
            let over = c.is_nan() || c.abs() > MAX_CORRECTION_MM;
            if over && worst.is_none_or(|w| c.abs() > w.2.abs()) {
                worst = Some((p, dir, c));
            }
        }
    }
    match worst {
        None => Ok(()),
        Some((position_mm, direction, correction_mm)) => Err(Error::CorrectionTooLarge {
            position_mm,
            direction,
            correction_mm,
            limit_mm: MAX_CORRECTION_MM,
            reference_mm: table.reference.position_mm(),
        }),
    }
}

/// Builds the compensation table of an evaluated ISO 230-2 run, referenced to `reference`.
///
/// What: per position P the corrections c↑(P), c↓(P) a controller adds to the commanded
/// position, mm, counted from the reference target P_r (c↑(P_r) = 0). Formula:
/// [`TableSource::Mean`]: positions = the targets in ascending order, c↑ = −(x̄_i↑ − x̄_r↑),
/// c↓ = −(x̄_i↓ − x̄_r↑) (ISO 230-2:2014 §3.9); [`TableSource::Model`]: positions on the
/// spacing from the first to the last target, c↑(P) = −(e(P, ↑) − e(P_r, ↑)),
/// c↓(P) = −(e(P, ↓) − e(P_r, ↑)) with e the fitted [`PitchModel`].
///
/// Reference: ISO 230-2:2014 §3.8–3.12; LinuxCNC's screw compensation and the reference
/// position of a controller's table (module docs).
///
/// Errors: a reference that is not a target ([`Error::Unresolvable`]), a correction beyond
/// [`MAX_CORRECTION_MM`] ([`Error::CorrectionTooLarge`]), and the model's refusals.
///
/// Known bad cases: the mean table carries each target's noise s_i/√n into the controller
/// (and the reference target's into every correction) and is linear between targets, so an
/// error shorter than the target spacing is not corrected (nor is it in any table from the
/// same run); the model table leaves out what its terms cannot express (see [`fit_model`]).
pub fn build_table(
    axis: &Axis230_2,
    source: TableSource,
    reference: Reference,
) -> Result<CompTable, Error> {
    let r = reference_target(axis, reference)?;
    let table = match source {
        TableSource::Mean => {
            let zero = axis.targets[r].mean_fwd;
            let mut rows: Vec<(f64, f64, f64)> = axis
                .targets
                .iter()
                .map(|t| (t.target_mm, zero - t.mean_fwd, zero - t.mean_bwd))
                .collect();
            rows.sort_by(|a, b| a.0.total_cmp(&b.0));
            CompTable {
                positions_mm: rows.iter().map(|r| r.0).collect(),
                forward_mm: rows.iter().map(|r| r.1).collect(),
                backward_mm: rows.iter().map(|r| r.2).collect(),
                model: None,
                spacing_mm: None,
                reference,
            }
        }
        TableSource::Model { cyclic, spacing_mm } => {
            let model = fit_model(axis, cyclic)?;
            let (lo, hi) = axis
                .targets
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |acc, t| {
                    (acc.0.min(t.target_mm), acc.1.max(t.target_mm))
                });
            let spacing = spacing_mm.unwrap_or_else(|| default_spacing_mm(hi - lo));
            let positions_mm = grid(lo, hi, spacing)?;
            let zero = model.deviation_mm(axis.targets[r].target_mm, true);
            let column = |forward: bool| -> Vec<f64> {
                positions_mm
                    .iter()
                    .map(|&p| zero - model.deviation_mm(p, forward))
                    .collect()
            };
            CompTable {
                forward_mm: column(true),
                backward_mm: column(false),
                positions_mm,
                model: Some(model),
                spacing_mm: Some(spacing),
                reference,
            }
        }
    };
    check_limit(&table)?;
    Ok(table)
}

impl CompTable {
    /// Number of positions.
    pub fn len(&self) -> usize {
        self.positions_mm.len()
    }

    /// Whether the table has no positions.
    pub fn is_empty(&self) -> bool {
        self.positions_mm.is_empty()
    }

    /// The correction the controller adds to a command at `position_mm` while moving in the
    /// positive (`forward`) or negative direction, mm.
    ///
    /// Formula: with P_k ≤ P < P_k+1, c = c_k + (c_k+1 − c_k)(P − P_k)/(P_k+1 − P_k); c_0 below
    /// the first position, c_last at and beyond the last.
    ///
    /// Reference: LinuxCNC `compute_screw_comp` (`src/emc/motion/control.c`) and the entry
    /// slopes of `EMCMOT_SET_JOINT_COMP` (`src/emc/motion/command.c`).
    ///
    /// Known bad cases: none (an empty table corrects nothing and returns 0).
    pub fn correction_mm(&self, position_mm: f64, forward: bool) -> f64 {
        let c = if forward {
            &self.forward_mm
        } else {
            &self.backward_mm
        };
        let p = &self.positions_mm;
        let Some(&last) = p.last() else {
            return 0.0;
        };
        if position_mm < p[0] {
            return c[0];
        }
        if position_mm >= last {
            return c[c.len() - 1];
        }
        let k = p.partition_point(|&x| x <= position_mm) - 1;
        c[k] + (c[k + 1] - c[k]) * (position_mm - p[k]) / (p[k + 1] - p[k])
    }

    /// The readings the axis would give with the table loaded: each reading P_ij plus the
    /// correction at its target in its approach direction, mm.
    ///
    /// Formula: P'_ij = P_ij + c_dir(P_i). To first order: commanded to P_i + c the axis reaches
    /// P_i + c + e(P_i + c) ≈ P_i + c + e(P_i), since the deviation e changes by
    /// |de/dP|·|c| (e.g. 30 µm/m × 30 µm ≈ 1 nm) over the correction.
    ///
    /// Reference: ISO 230-2:2014 §3.8 (deviation = measured − target).
    ///
    /// Known bad cases: an error that changes by a resolvable amount within the size of the
    /// correction (none on a screw-driven axis).
    pub fn apply(&self, readings: &PositionTable) -> PositionTable {
        let shift = |rows: &[Vec<f64>], forward: bool| -> Vec<Vec<f64>> {
            rows.iter()
                .zip(&readings.targets_mm)
                .map(|(row, &p)| {
                    let c = self.correction_mm(p, forward);
                    row.iter().map(|x| x + c).collect()
                })
                .collect()
        };
        PositionTable {
            targets_mm: readings.targets_mm.clone(),
            forward_mm: shift(&readings.forward_mm, true),
            backward_mm: shift(&readings.backward_mm, false),
        }
    }

    /// The ISO 230-2 figures of `readings` as measured and as they would be with the table
    /// loaded ([`CompTable::apply`]): `(before, after)`.
    pub fn predict(&self, readings: &PositionTable) -> Result<(Axis230_2, Axis230_2), Error> {
        Ok((
            evaluate_table(readings)?,
            evaluate_table(&self.apply(readings))?,
        ))
    }
}

#[cfg(test)]
pub(crate) mod tests;
