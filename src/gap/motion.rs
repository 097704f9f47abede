//! Motion-domain diagnosis: simulate, localise, fit every effect by re-simulation, select by
//! blocked cross-validation with a "none" rule, report gap before/after and validation.

use std::borrow::Cow;

use serde::Serialize;

use crate::gap::Error;
use crate::gap::align::{fill_unobserved, masked_stats, observed_only};
use crate::gap::effects::{Effect, Fitted};
use crate::gap::events::{Span, rank_spans};
use crate::gap::fit::{SimCache, at_bound};
pub use crate::gap::judge::noise_sigma;
use crate::gap::judge::{Outcome, judge, validation_left};
use crate::gap::patterns::{Pattern, patterns};
use crate::gap::plant::{AxisPlant, stored_simulation};
use crate::gap::steps::{Model, Problem, compose, cross_validate_observed};
use crate::gap::unexplained::{Periodic, periodic_components};
use crate::gap::usual::warnings;
use crate::motion::{ServoAxis, StructuralMode};
use crate::numeric::parallel::map_dynamic;

/// One block of samples, per axis columns (mm), sample `i` at `t = i·period_s`.
#[derive(Clone, Debug, Default)]
pub struct MotionBlock {
    /// Commanded positions per axis.
    pub commanded: Vec<Vec<f64>>,
    /// Measured positions per axis.
    pub measured: Vec<Vec<f64>>,
}

/// Tuning of the selection.
#[derive(Clone, Debug)]
pub struct MotionOptions {
    /// Contiguous cross-validation folds.
    pub folds: usize,
    /// Smallest held-out fraction of the squared gap an effect must remove to be the verdict.
    pub min_score: f64,
    /// Smallest held-out mean-square improvement, in units of the noise variance estimate.
    pub min_improvement_noise: f64,
    /// Spans reported in `where`.
    pub max_spans: usize,
    /// Worker threads for the effect fits (1 = single-threaded).
    pub threads: usize,
    /// Most effects added one after another in `steps`.
    pub max_steps: usize,
    /// Smallest held-out fraction of the gap above the noise that the steps together must
    /// remove for the verdict to name an effect; below it the verdict is `unexplained`.
    pub min_explained: f64,
    /// Smallest mean-square gap above the noise, in units of the noise variance per axis,
    /// for a gap to count as more than noise (below it: a named effect or `none`, never
    /// `unexplained`).
    pub min_excess_noise: f64,
    /// Largest share of a validation block's gap above the noise that the steps (fitted on
    /// the main block) may leave for an effect to be named (`validation_share`).
    pub max_validation_left: f64,
    /// Weight per main-block sample: 1 where a log sample backs it, 0 where none does (a
    /// time-stamped log on the program's grid, [`crate::gap::align`]); `None`: every sample.
    pub observed: Option<Vec<f64>>,
    /// Effects stored with the machine, added to the stored simulation the gap is measured
    /// against ("as simulated"; default: none).
    pub prior: crate::motion::Effects,
}

impl Default for MotionOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            min_score: 0.05,
            min_improvement_noise: 0.1,
            max_spans: 20,
            threads: 2,
            max_steps: 4,
            // tuned on self-check seeds 20000-20011 (kinds 1-8): library truths left at most
            // 10 % of the held-out gap above the noise (most 0 %), out-of-library ones
            // 31-56 % (a library effect removing 44-69 % of it)
            min_explained: 0.8,
            min_excess_noise: 1.0,
            // tuned on self-check tuning seeds (outside 20000-20047, wide 1-130): 0.3 turned a
            // library pair unexplained, 0.5 kept one more out-of-library plant named
            max_validation_left: 0.4,
            observed: None,
            prior: crate::motion::Effects::default(),
        }
    }
}

/// RMS and max of the per-sample error-vector length, mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GapStats {
    /// Root mean square of |measured − simulated|, mm.
    pub rms: f64,
    /// Maximum of |measured − simulated|, mm.
    pub max: f64,
}

/// One effect of the ranked list.
#[derive(Clone, Debug)]
pub struct EffectResult {
    /// Fitted on all the main data.
    pub fitted: Fitted,
    /// Named parameters (units in the names).
    pub params: Vec<(String, f64)>,
    /// Held-out fraction of the squared gap removed (blocked CV), ≤ 1; negative = worse.
    pub score: f64,
    /// Parameters still at a bound of their widened search (names as in `params`).
    pub at_bound: Vec<String>,
    /// Sizes outside the effect's usual range: why unusual, what commonly causes them
    /// ([`crate::gap::usual::warnings`]).
    pub warnings: Vec<String>,
}

/// One step of the forward selection: the effect added, fitted jointly with the earlier ones.
#[derive(Clone, Debug)]
pub struct StepResult {
    /// The added effect's parameters in the joint fit of this step (all the main data).
    pub fitted: Fitted,
    /// Named parameters (units in the names).
    pub params: Vec<(String, f64)>,
    /// Parameters that ended at a bound of their search (always empty for a chosen step).
    pub at_bound: Vec<String>,
    /// Sizes outside the effect's usual range ([`crate::gap::usual::warnings`]).
    pub warnings: Vec<String>,
    /// Measured vs simulation with this and all earlier steps' effects.
    pub gap_after: GapStats,
    /// Held-out fraction of the remaining squared gap this step removed.
    pub score: f64,
}

/// What the steps leave unexplained.
#[derive(Clone, Debug)]
pub struct Unexplained {
    /// RMS of |measured − simulation with every step|, mm.
    pub rms: f64,
    /// Part of the original squared gap left, 0..1.
    pub share: f64,
    /// Part of the held-out squared gap above the noise that the steps leave, 0..1 (1 with
    /// no step): `Σ SSE_held(steps) − n·d·σ̂²` over `Σ SSE_held(stored) − n·d·σ̂²`.
    pub heldout_share: f64,
    /// With a validation block: the share of its squared gap above the noise that the steps,
    /// fitted on the main block only, leave ([`crate::gap::judge::validation_share`]; may
    /// exceed 1); `None` without one, when its gap is at the noise, or when the first step is
    /// a thermal drift.
    pub validation_share: Option<f64>,
    /// Strongest periodic components of the rest.
    pub periodic: Vec<Periodic>,
    /// What the rest is tied to (time, position, an event, speed, direction, a jump).
    pub patterns: Vec<Pattern>,
}

/// Validation predictions (per axis columns, mm) without and with the verdict's effect.
#[derive(Clone, Debug)]
pub struct MotionValidation {
    /// Stored simulation of the validation command.
    pub predicted_before: Vec<Vec<f64>>,
    /// With the verdict's effect (fitted on the main block only).
    pub predicted_after: Vec<Vec<f64>>,
    /// RMS of |measured − predicted_before|, mm.
    pub rms_before: f64,
    /// RMS of |measured − predicted_after|, mm.
    pub rms_after: f64,
    /// The prediction after each step (fitted on the main block only).
    pub predicted_steps: Vec<Vec<Vec<f64>>>,
    /// RMS of `|measured − predicted_steps[m]|` per step, mm.
    pub rms_steps: Vec<f64>,
}

/// The answer of a motion diagnosis.
#[derive(Clone, Debug)]
pub struct MotionDiagnosis {
    /// Measured vs stored simulation.
    pub gap_before: GapStats,
    /// Worst spans first.
    pub spans: Vec<Span>,
    /// Every library effect, best score first.
    pub effects: Vec<EffectResult>,
    /// The effect found, or `Effect::None`.
    pub verdict: Effect,
    /// Measured vs simulation with the verdict's effect.
    pub gap_after: GapStats,
    /// Effects added one after another while the held-out score improves.
    pub steps: Vec<StepResult>,
    /// What the steps leave.
    pub unexplained: Unexplained,
    /// Present when a validation block was given.
    pub validation: Option<MotionValidation>,
    /// Noise standard deviation estimated from the residual, mm.
    pub noise_mm: f64,
}

/// Gap statistics of `measured − simulated` (per axis columns, mm).
pub fn gap_stats(measured: &[Vec<f64>], simulated: &[Vec<f64>]) -> GapStats {
    let n = measured.first().map_or(0, Vec::len);
    let (mut sum, mut max) = (0.0, 0.0f64);
    for i in 0..n {
        let e2: f64 = measured
            .iter()
            .zip(simulated)
            .map(|(m, s)| (m[i] - s[i]).powi(2))
            .sum();
        sum += e2;
        max = max.max(e2.sqrt());
    }
    GapStats {
        rms: if n > 0 { (sum / n as f64).sqrt() } else { 0.0 },
        max,
    }
}

fn check_block(
    field: &str,
    block: &MotionBlock,
    dims: usize,
    min_len: usize,
) -> Result<usize, Error> {
    if block.commanded.len() != dims || block.measured.len() != dims {
        return Err(Error::shape(
            field,
            format!("every row needs {dims} columns (one per servo axis of the machine)"),
        ));
    }
    let n = block.commanded[0].len();
    if n < min_len {
        return Err(Error::shape(
            field,
            format!("needs at least {min_len} samples, got {n}"),
        ));
    }
    for (name, cols) in [
        ("commanded", &block.commanded),
        ("measured", &block.measured),
    ] {
        for col in cols {
            if col.len() != n {
                return Err(Error::shape(
                    &format!("{field}.{name}"),
                    format!("has a different number of rows than {field}.commanded ({n})"),
                ));
            }
            if let Some(index) = col.iter().position(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    field: format!("{field}.{name}"),
                    index,
                });
            }
        }
    }
    Ok(n)
}

/// Diagnoses the sim-to-real gap of a motion block (openapi.yaml
/// `POST /v1/machines/{machine}/gap-diagnosis`, domain `motion`). `axes` are the axis letters
/// and `servo` their stored models, in column order.
///
/// Each library effect is fitted by re-simulation on `folds − 1` contiguous folds and scored on
/// the held-out fold: `score = 1 − Σ SSE_effect / Σ SSE_stored` over folds. An effect is a
/// step if its score ≥ `min_score` and its held-out mean-square improvement exceeds
/// `min_improvement_noise·σ̂²` (σ̂ from [`noise_sigma`]). The verdict is the first step's
/// effect when the steps together remove at least `min_explained` of the held-out squared gap
/// above the noise, `1 − (SSE_held(steps) − n·d·σ̂²) / (SSE_held(stored) − n·d·σ̂²)`;
/// `unexplained` when they do not and the gap's mean-square excess over the noise is at
/// least `min_excess_noise·d·σ̂²`; otherwise the first step or `none`. Parameters reported
/// are refitted on all the main data. Bad cases: effects too small for the program to excite
/// (e.g. scale on a tiny stroke near zero) are answered `none`; a σ̂ far off the true noise
/// (quantized or filtered logs) moves the line between `none`, a name and `unexplained`.
pub fn diagnose_motion(
    axes: &[String],
    servo: &[ServoAxis],
    period_s: f64,
    main: &MotionBlock,
    validation: Option<&MotionBlock>,
    opts: &MotionOptions,
) -> Result<MotionDiagnosis, Error> {
    diagnose_motion_structured(axes, servo, &[], period_s, main, validation, None, opts)
}

/// As [`diagnose_motion`], with the machine's structural mode per axis (Zhang & Chen 2025 eq. 10)
/// between motor and table (`structure[k]`, missing entries = rigid), as the contour
/// prediction simulates it, and the program `lines` executing at each sample when the command
/// came from a program (named in `where`).
///
/// After the verdict, effects are added one after another ([`crate::gap::steps`]): each
/// remaining effect is fitted jointly with those chosen and scored on the held-out folds
/// against the model so far, with the same rule (`min_score` of the remaining held-out squared
/// gap, `min_improvement_noise·σ̂²`); an effect whose parameter is still at a bound of its
/// widened search ([`crate::gap::fit::at_bound`]) is never chosen. No size is vetoed: a size
/// outside the effect's usual range is chosen on its held-out score and carries a warning. `unexplained` is what the steps leave.
#[allow(clippy::too_many_arguments)]
pub fn diagnose_motion_structured(
    axes: &[String],
    servo: &[ServoAxis],
    structure: &[Option<StructuralMode>],
    period_s: f64,
    main: &MotionBlock,
    validation: Option<&MotionBlock>,
    lines: Option<&[u32]>,
    opts: &MotionOptions,
) -> Result<MotionDiagnosis, Error> {
    if !period_s.is_finite() || period_s <= 0.0 || period_s > 10.0 {
        return Err(Error::Invalid {
            field: "period_s".into(),
            value: period_s,
            reason: "it must be a positive number of seconds (at most 10)".into(),
        });
    }
    let dims = servo.len();
    if !(1..=3).contains(&dims) || axes.len() != dims {
        return Err(Error::shape(
            "commanded",
            "rows need 2 or 3 columns ([x, y] or [x, y, z])",
        ));
    }
    let folds = opts.folds.max(2);
    let n = check_block("commanded", main, dims, 10 * folds)?;
    if let Some(v) = validation {
        check_block("validation", v, dims, 2)?;
    }
    let plants: Vec<AxisPlant> = axes
        .iter()
        .zip(servo)
        .enumerate()
        .map(|(k, (a, s))| {
            AxisPlant::new(a, s, period_s)
                .map(|p| p.with_structure(structure.get(k).copied().flatten()))
        })
        .collect::<Result<_, _>>()?;
    // the stored simulation: the linear cascade plus the effects stored with the machine
    let simulate = |cmd: &[Vec<f64>]| stored_simulation(&plants, axes, &opts.prior, cmd);
    let base = simulate(&main.commanded)?;
    let residual: Vec<Vec<f64>> = main
        .measured
        .iter()
        .zip(&base)
        .map(|(m, b)| m.iter().zip(b).map(|(m, b)| m - b).collect())
        .collect();
    // a time-stamped log observes only some grid instants: fits, scores and statistics read
    // those; localisation reads the residual filled in between them
    let observed = opts.observed.as_deref();
    if observed.is_some_and(|w| w.len() != n) {
        return Err(Error::shape(
            "observed",
            "needs one weight per sample of the block",
        ));
    }
    let gap_before = masked_stats(&main.measured, &base, observed);
    let filled = fill_unobserved(&residual, observed);
    let mut spans = rank_spans(&main.commanded, &filled, axes, opts.max_spans);
    if let Some(lines) = lines {
        // an event at sample j is the motion from j to j + 1: the line of sample j + 1 runs it
        for s in spans.iter_mut() {
            let at = if s.start == 0 {
                0
            } else {
                (s.start + 1).min(n - 1)
            };
            s.line = lines.get(at).copied();
        }
    }
    let noise = noise_sigma(&observed_only(Cow::Borrowed(residual.as_slice()), observed));
    let cache = SimCache::default();
    let problem = Problem {
        plants: &plants,
        cmd: &main.commanded,
        meas: &main.measured,
        base: &base,
        cache: &cache,
    };
    let duration = (n - 1) as f64 * period_s;
    let all = observed.map_or_else(|| vec![1.0; n], <[f64]>::to_vec);
    let n_observed = all.iter().filter(|w| **w > 0.0).count().max(1);
    let threshold = opts.min_improvement_noise * noise * noise;

    // forward selection: step 0 scores every library effect against "none" (the `effects`
    // list); each later step scores the remaining effects against the model chosen so far
    let mut fold_models = vec![Model::default(); folds];
    let mut full = Model::default();
    let mut effects: Vec<EffectResult> = Vec::new();
    let mut steps: Vec<StepResult> = Vec::new();
    let mut step_models: Vec<Model> = Vec::new();
    // held-out squared gap of the stored simulation and of the steps so far (mm²); every
    // sample is held out once, so the stored one is the whole residual's
    let mut held_stored: f64 = residual.iter().flatten().map(|r| r * r).sum();
    let mut held_left = held_stored;
    while steps.len() < opts.max_steps {
        crate::numeric::stop::check();
        let candidates: Vec<Effect> = Effect::LIBRARY
            .iter()
            .copied()
            .filter(|e| !full.members.iter().any(|m| m.effect() == *e))
            .collect();
        if candidates.is_empty() {
            break;
        }
        let results = map_dynamic(&candidates, opts.threads, |effect| {
            let (models, held_new, held_old) =
                cross_validate_observed(&problem, &fold_models, effect, &all);
            let joint = full.with(&problem, effect, &all, 2);
            (models, held_new, held_old, joint)
        });
        let mut scored: Vec<Candidate> = results
            .into_iter()
            .map(|(models, held_new, held_old, joint)| {
                let fitted = joint.members.last().cloned().unwrap_or(Fitted::None);
                let score = if held_old > 0.0 {
                    1.0 - held_new / held_old
                } else {
                    0.0
                };
                Candidate {
                    at_bound: at_bound(&fitted, axes, &plants, duration),
                    warnings: warnings(&fitted, axes, &plants, duration),
                    score: if score.is_finite() {
                        score
                    } else {
                        f64::NEG_INFINITY
                    },
                    gain: (held_old - held_new) / (n_observed * dims) as f64,
                    held_new,
                    held_old,
                    fitted,
                    models,
                    joint,
                }
            })
            .collect();
        scored.sort_by(|a, b| b.score.total_cmp(&a.score));
        if steps.is_empty() {
            // the ranked list: every effect alone, whatever its size (no veto by size: an
            // unusual size carries its warning)
            effects = scored
                .iter()
                .map(|c| EffectResult {
                    params: c.fitted.params(axes, &plants, duration),
                    fitted: c.fitted.clone(),
                    score: c.score,
                    at_bound: c.at_bound.clone(),
                    warnings: c.warnings.clone(),
                })
                .collect();
        }
        let Some(best) = scored
            .into_iter()
            .find(|c| c.at_bound.is_empty() && c.score >= opts.min_score && c.gain >= threshold)
        else {
            break;
        };
        if steps.is_empty() {
            held_stored = best.held_old;
        }
        held_left = best.held_new;
        fold_models = best.models;
        full = best.joint;
        let pred = full.predict(&base);
        steps.push(StepResult {
            params: best.fitted.params(axes, &plants, duration),
            at_bound: best.at_bound,
            warnings: best.warnings,
            fitted: best.fitted,
            gap_after: masked_stats(&main.measured, &pred, observed),
            score: best.score,
        });
        step_models.push(full.clone());
    }
    // the validation block, predicted by the steps fitted on the main block alone
    let vsim = match validation {
        Some(v) => {
            let vbase = simulate(&v.commanded)?;
            let steps_v = step_models.iter();
            let steps_v = steps_v.map(|m| compose(&m.members, &plants, &v.commanded, &vbase));
            Some((steps_v.collect::<Vec<_>>(), vbase))
        }
        None => None,
    };
    // a drift depends on the time since a warm-up the block does not show: not tested there
    let drift = steps.first().map(|s| s.fitted.effect()) == Some(Effect::ThermalDrift);
    let vshare = match (validation, &vsim) {
        (Some(v), Some((sv, vb))) if !drift => sv
            .last()
            .and_then(|l| validation_left(&v.measured, vb, l, opts.min_excess_noise)),
        _ => None,
    };
    // "none of these": a gap well above the noise that the steps together do not remove
    // most of on held-out data, or whose removal does not carry over to the validation
    // block, is unexplained, even when a step removes part of it
    let (outcome, heldout_share) = judge(
        held_stored,
        held_left,
        noise,
        n_observed * dims,
        !steps.is_empty(),
        opts.min_explained,
        opts.min_excess_noise,
        vshare,
        opts.max_validation_left,
    );
    let unexplained_verdict = outcome == Outcome::Unexplained;
    let chosen = match steps.first() {
        Some(s) if !unexplained_verdict => s.fitted.clone(),
        _ => Fitted::None,
    };
    let verdict = if unexplained_verdict {
        Effect::Unexplained
    } else {
        chosen.effect()
    };
    let gap_after = match steps.first() {
        Some(s) if !unexplained_verdict => s.gap_after,
        _ => gap_before,
    };
    let after_all = full.predict(&base);
    let rest: Vec<Vec<f64>> = main
        .measured
        .iter()
        .zip(&after_all)
        .map(|(m, p)| m.iter().zip(p).map(|(m, p)| m - p).collect())
        .collect();
    let left = masked_stats(&main.measured, &after_all, observed);
    let unexplained = Unexplained {
        rms: left.rms,
        share: if gap_before.rms > 0.0 {
            (left.rms / gap_before.rms).powi(2)
        } else {
            0.0
        },
        heldout_share,
        validation_share: vshare,
        periodic: periodic_components(&fill_unobserved(&rest, observed), &base, axes, period_s),
        patterns: patterns(
            &fill_unobserved(&rest, observed),
            &main.commanded,
            &base,
            axes,
            period_s,
        ),
    };

    let validation = validation.zip(vsim).map(|(v, (predicted_steps, vbase))| {
        let vafter = chosen.predict(&plants, &v.commanded, &vbase);
        MotionValidation {
            rms_before: gap_stats(&v.measured, &vbase).rms,
            rms_after: gap_stats(&v.measured, &vafter).rms,
            rms_steps: predicted_steps
                .iter()
                .map(|p| gap_stats(&v.measured, p).rms)
                .collect(),
            predicted_before: vbase,
            predicted_after: vafter,
            predicted_steps,
        }
    });
    Ok(MotionDiagnosis {
        gap_before,
        spans,
        effects,
        verdict,
        gap_after,
        steps,
        unexplained,
        validation,
        noise_mm: noise,
    })
}

/// One candidate of a selection step.
struct Candidate {
    fitted: Fitted,
    at_bound: Vec<String>,
    warnings: Vec<String>,
    score: f64,
    gain: f64,
    held_new: f64,
    held_old: f64,
    models: Vec<Model>,
    joint: Model,
}

#[cfg(test)]
mod tests;
