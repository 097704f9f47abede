//! Compensated programs with the effects stored with the machine (issue 40 item 2): what a
//! program can correct in its points is corrected there — the geometric effects (scale,
//! squareness, cyclic error) as p − e(p), as a volumetric map is, backlash by offsets and
//! take-up moves at reversals, thermal drift by its value at each line's time — and the
//! others (friction, gain) by the contour pass on the servo model. The answer is judged on
//! the machine with every stored effect, against the path as programmed.

use std::sync::Arc;

use crate::cam::{self, Compensated, ErrorField, Predistorted};
use crate::gap::adopted::StoredEffects;
use crate::motion::{AddedEffects, Effects, Machine, ReadOptions};
use crate::volumetric::VolumetricMap;

/// The geometric effects stored with a machine (see [`StoredEffects::geometric_error_at`]) as
/// the error field a program is compensated against. They hold over the whole travel: no
/// point is outside.
struct EffectsField(Arc<StoredEffects>);

impl ErrorField for EffectsField {
    fn error_at(&self, p: [f64; 3]) -> [f64; 3] {
        self.0.geometric_error_at(p)
    }

    fn contains(&self, _p: [f64; 3]) -> bool {
        true
    }
}

/// The request's program and options.
pub struct Job<'a> {
    /// The program text.
    pub gcode: &'a str,
    /// How it is read.
    pub options: &'a ReadOptions,
    /// Tolerance of the corrected path, mm.
    pub tolerance_mm: f64,
    /// The contour pass' options.
    pub opts: &'a cam::PredistortOptions,
}

/// The program of `job` corrected against `corrected` (the stored set's part a program
/// corrects in its points, [`StoredEffects::split_corrected`]; added to `map`'s errors when
/// given) and pre-distorted on `machine`'s servo model with `rest` (the other effects), its
/// figures those of the program as written on `machine` (which carries every stored effect)
/// against the path as programmed, with a warning that says so.
pub fn corrected(
    job: &Job<'_>,
    map: Option<&VolumetricMap>,
    machine: &Machine,
    corrected: Arc<StoredEffects>,
    rest: Arc<StoredEffects>,
) -> Result<(Compensated, Predistorted), cam::Error> {
    let effects = EffectsField(corrected.clone());
    let sum;
    let field: &dyn ErrorField = match map {
        Some(map) => {
            sum = cam::SumField(map, &effects);
            &sum
        }
        None => &effects,
    };
    let mut servo = machine.clone();
    servo.effects = if rest.is_empty() {
        Effects(None)
    } else {
        Effects(Some(rest as Arc<dyn AddedEffects>))
    };
    // the drift at each line's time, on the program's own clock
    let drift_mm = cam::line_end_times(job.gcode, job.options, machine, job.opts.period_s)?
        .into_iter()
        .map(|t| corrected.drift_at(t))
        .collect();
    let offsets = cam::Offsets {
        backlash_mm: corrected.backlash_mm(),
        drift_mm,
    };
    let (mut out, mut p) = cam::corrected_and_contour(
        job.gcode,
        job.options,
        (field, &offsets),
        job.tolerance_mm,
        &servo,
        job.opts,
    )?;
    let models = cam::judge_written(job.gcode, job.options, machine, job.opts, &out.gcode)?;
    p.original = models[0].original;
    p.compensated = models[0].compensated;
    p.models = models;
    out.warnings.push(format!(
        "effects stored with the machine ({}; effects version {}) corrected in the commanded \
         points: geometric ones as p - e(p){}, backlash by half the play along each axis' \
         direction and take-up moves at reversals, thermal drift by its value at each line's \
         time from the program's start (a drift that began before the program is not known); \
         the other stored effects by the contour pass on the servo model; the contour figures \
         are those of the program as written, simulated with every stored effect, against the \
         path as programmed",
        corrected.names().join(", "),
        machine.effects.version().unwrap_or_default(),
        if map.is_some() {
            ", added to the volumetric map's errors (max_shift_mm is the sum's)"
        } else {
            " (max_shift_mm is theirs)"
        }
    ));
    Ok((out, p))
}
