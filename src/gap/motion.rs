//! Motion-domain diagnosis: simulate, localise, fit every effect by re-simulation, select by
//! blocked cross-validation with a "none" rule, report gap before/after and validation.

use serde::Serialize;

use crate::gap::Error;
use crate::gap::effects::{Effect, Fitted};
use crate::gap::events::{Span, rank_spans};
use crate::gap::fit::{FitData, fit, sse};
use crate::gap::plant::AxisPlant;
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
}

impl Default for MotionOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            min_score: 0.05,
            min_improvement_noise: 0.1,
            max_spans: 20,
            threads: 2,
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

/// Noise standard deviation of a residual (mm): `1.4826·median|Δ²r| / √6` pooled over axes —
/// white noise of variance σ² has second differences of variance 6σ², while the smooth part of
/// the gap barely contributes; never below half the RMS-based estimate `rms(Δ²r)/√6`
/// (quantized data make the median of |Δ²r| nearly 0). Bad cases: gaps with many
/// steps per sample inflate it.
pub fn noise_sigma(residual: &[Vec<f64>]) -> f64 {
    let mut d2: Vec<f64> = residual
        .iter()
        .flat_map(|r| r.windows(3).map(|w| (w[0] - 2.0 * w[1] + w[2]).abs()))
        .collect();
    if d2.is_empty() {
        return 0.0;
    }
    let rms = (d2.iter().map(|d| d * d).sum::<f64>() / d2.len() as f64).sqrt() / 6f64.sqrt();
    let mid = d2.len() / 2;
    let (_, m, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    let robust = 1.4826 * *m / 6f64.sqrt();
    // quantized measurements (most second differences exactly or nearly 0) make the median
    // useless: never report less than half the RMS-based estimate (steps and spikes of a real
    // gap inflate the RMS one, hence only half of it)
    robust.max(0.5 * rms)
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
/// the held-out fold: `score = 1 − Σ SSE_effect / Σ SSE_stored` over folds. The verdict is the
/// best effect if its score ≥ `min_score` and its held-out mean-square improvement exceeds
/// `min_improvement_noise·σ̂²` (σ̂ from [`noise_sigma`]); otherwise `none`. Parameters reported
/// are refitted on all the main data. Bad cases: effects too small for the program to excite
/// (e.g. scale on a tiny stroke near zero) are answered `none`.
pub fn diagnose_motion(
    axes: &[String],
    servo: &[ServoAxis],
    period_s: f64,
    main: &MotionBlock,
    validation: Option<&MotionBlock>,
    opts: &MotionOptions,
) -> Result<MotionDiagnosis, Error> {
    diagnose_motion_structured(axes, servo, &[], period_s, main, validation, opts)
}

/// As [`diagnose_motion`], with the machine's structural mode per axis (Zhang & Chen 2025 eq. 10)
/// between motor and table (`structure[k]`, missing entries = rigid), as the contour
/// prediction simulates it.
pub fn diagnose_motion_structured(
    axes: &[String],
    servo: &[ServoAxis],
    structure: &[Option<StructuralMode>],
    period_s: f64,
    main: &MotionBlock,
    validation: Option<&MotionBlock>,
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
    let base: Vec<Vec<f64>> = plants
        .iter()
        .zip(&main.commanded)
        .map(|(p, c)| p.linear(c))
        .collect();
    let residual: Vec<Vec<f64>> = main
        .measured
        .iter()
        .zip(&base)
        .map(|(m, b)| m.iter().zip(b).map(|(m, b)| m - b).collect())
        .collect();
    let gap_before = gap_stats(&main.measured, &base);
    let spans = rank_spans(&main.commanded, &residual, axes, opts.max_spans);
    let noise = noise_sigma(&residual);
    let data = FitData {
        plants: &plants,
        cmd: &main.commanded,
        meas: &main.measured,
        base: &base,
        cache: Default::default(),
    };

    let fold_of = |i: usize| i * folds / n;
    let evaluate = |effect: Effect| -> (Fitted, f64, f64) {
        let all = vec![1.0; n];
        let full = fit(effect, &data, &all, None);
        let (mut held_eff, mut held_none) = (0.0, 0.0);
        for j in 0..folds {
            let train: Vec<f64> = (0..n)
                .map(|i| if fold_of(i) == j { 0.0 } else { 1.0 })
                .collect();
            let test: Vec<f64> = train.iter().map(|w| 1.0 - w).collect();
            let fitted = fit(effect, &data, &train, Some(&full));
            let pred = fitted.predict(&plants, &main.commanded, &base);
            let (he, hn) = (held_eff, held_none);
            for k in 0..dims {
                held_eff += sse(&main.measured[k], &pred[k], &test);
                held_none += sse(&main.measured[k], &base[k], &test);
            }
            if std::env::var("GAP_DEBUG").is_ok()
                && matches!(effect, Effect::Backlash | Effect::CoulombFriction)
            {
                eprintln!(
                    "fold {j} {effect:?} eff {:.3e} none {:.3e} {fitted:?}",
                    held_eff - he,
                    held_none - hn
                );
            }
        }
        let fitted = full;
        let score = if held_none > 0.0 {
            1.0 - held_eff / held_none
        } else {
            0.0
        };
        (fitted, score, (held_none - held_eff) / (n * dims) as f64)
    };
    let results = map_dynamic(&Effect::LIBRARY, opts.threads, evaluate);

    let duration = (n - 1) as f64 * period_s;
    let mut effects: Vec<(EffectResult, f64)> = results
        .into_iter()
        .map(|(fitted, score, gain)| {
            let params = fitted.params(axes, &plants, duration);
            (
                EffectResult {
                    fitted,
                    params,
                    score: if score.is_finite() {
                        score
                    } else {
                        f64::NEG_INFINITY
                    },
                },
                gain,
            )
        })
        .collect();
    effects.sort_by(|a, b| b.0.score.total_cmp(&a.0.score));
    let chosen = effects
        .first()
        .filter(|(e, gain)| {
            e.score >= opts.min_score && *gain >= opts.min_improvement_noise * noise * noise
        })
        .map(|(e, _)| e.fitted.clone())
        .unwrap_or(Fitted::None);
    let verdict = chosen.effect();
    let after = chosen.predict(&plants, &main.commanded, &base);
    let gap_after = gap_stats(&main.measured, &after);

    let validation = validation.map(|v| {
        let vbase: Vec<Vec<f64>> = plants
            .iter()
            .zip(&v.commanded)
            .map(|(p, c)| p.linear(c))
            .collect();
        let vafter = chosen.predict(&plants, &v.commanded, &vbase);
        MotionValidation {
            rms_before: gap_stats(&v.measured, &vbase).rms,
            rms_after: gap_stats(&v.measured, &vafter).rms,
            predicted_before: vbase,
            predicted_after: vafter,
        }
    });
    Ok(MotionDiagnosis {
        gap_before,
        spans,
        effects: effects.into_iter().map(|e| e.0).collect(),
        verdict,
        gap_after,
        validation,
        noise_mm: noise,
    })
}

#[cfg(test)]
mod tests;
