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
mod tests {
    #![allow(clippy::needless_range_loop)]
    use super::*;
    use crate::gap::truth::{Truth, measure};
    use rand::SeedableRng;

    fn servo() -> Vec<ServoAxis> {
        vec![
            ServoAxis {
                kv: 30.0,
                kff: 0.0,
                kp_v: Some(400.0),
                ti_v: Some(0.01),
                tc: Some(0.0006),
            },
            ServoAxis {
                kv: 30.0,
                kff: 0.0,
                kp_v: Some(400.0),
                ti_v: Some(0.01),
                tc: Some(0.0006),
            },
        ]
    }

    /// A circle of radius 20 mm about (200, 100) mm at 40 mm/s for 7 s (about 2.2 turns),
    /// `dir` = +1 CCW, −1 CW, with 0.2 s speed ramps; returns the command per axis.
    fn circle(dir: f64) -> Vec<Vec<f64>> {
        let (r, v, total) = (20.0, 40.0, 7.0);
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for i in 0..7001 {
            let t = i as f64 * 0.001;
            let s = if t < 0.2 {
                v * t * t / 0.4
            } else if t < total - 0.2 {
                v * (t - 0.1)
            } else {
                v * (total - 0.2) - v * (total - t).powi(2) / 0.4
            };
            let th = dir * s / r;
            x.push(200.0 + r * th.cos());
            y.push(100.0 + r * th.sin());
        }
        vec![x, y]
    }

    fn names() -> Vec<String> {
        vec!["X".into(), "Y".into()]
    }

    /// Orientation (deg) of the 2θ term of the radial deviation about the centre.
    fn ellipse_angle(pos: &[Vec<f64>]) -> f64 {
        let (mut a, mut b) = (0.0, 0.0);
        // exactly one turn at constant speed: 2π·20/40 s
        for i in 1000..1000 + 3142 {
            let (dx, dy) = (pos[0][i] - 200.0, pos[1][i] - 100.0);
            let th = dy.atan2(dx);
            let dr = dx.hypot(dy) - 20.0;
            a += dr * (2.0 * th).cos();
            b += dr * (2.0 * th).sin();
        }
        0.5 * b.atan2(a).to_degrees()
    }

    #[test]
    fn ballbar_mismatch_flips_between_cw_and_ccw_squareness_does_not() {
        let plants: Vec<AxisPlant> = servo()
            .iter()
            .map(|s| AxisPlant::new("X", s, 0.001).unwrap())
            .collect();
        let mismatch = Fitted::ServoGainMismatch {
            kv: vec![30.0, 36.0],
        };
        let square = Fitted::AxisSquareness {
            target: 0,
            source: 1,
            alpha: 200e-6,
        };
        let mut angles = Vec::new();
        for dir in [1.0, -1.0] {
            let cmd = circle(dir);
            let base: Vec<Vec<f64>> = plants.iter().zip(&cmd).map(|(p, c)| p.linear(c)).collect();
            let a_m = ellipse_angle(&mismatch.predict(&plants, &cmd, &base));
            let a_s = ellipse_angle(&square.predict(&plants, &cmd, &base));
            angles.push((a_m, a_s));
        }
        let ((m_ccw, s_ccw), (m_cw, s_cw)) = (angles[0], angles[1]);
        // both are 45° ellipses; only the mismatch one turns by 90° with the direction
        for a in [m_ccw, m_cw, s_ccw, s_cw] {
            assert!((a.abs() - 45.0).abs() < 3.0, "{angles:?}");
        }
        assert!(m_ccw * m_cw < 0.0, "mismatch must flip: {angles:?}");
        assert!(s_ccw * s_cw > 0.0, "squareness must not flip: {angles:?}");
    }

    #[test]
    fn friction_spike_decays_backlash_step_persists_and_the_diagnosis_tells_them_apart() {
        let servo = servo();
        let cmd = circle(1.0);
        let plants: Vec<AxisPlant> = servo
            .iter()
            .map(|s| AxisPlant::new("X", s, 0.001).unwrap())
            .collect();
        let base: Vec<Vec<f64>> = plants.iter().zip(&cmd).map(|(p, c)| p.linear(c)).collect();
        // Y reverses at θ = 90° (sample ≈ 885): look at the Y residual after it
        let rev = (1..cmd[1].len() - 1)
            .find(|&i| cmd[1][i + 1] < cmd[1][i])
            .unwrap();
        let fr = Fitted::CoulombFriction {
            f: vec![200.0, 200.0],
        }
        .predict(&plants, &cmd, &base);
        let bl = Fitted::Backlash {
            b: vec![0.01, 0.01],
            start: vec![0.0, 0.0],
        }
        .predict(&plants, &cmd, &base);
        let res = |p: &[Vec<f64>], i: usize| (p[1][i] - base[1][i]).abs();
        let peak_f = (rev..rev + 150).map(|i| res(&fr, i)).fold(0.0, f64::max);
        assert!(peak_f > 0.002, "friction glitch {peak_f}");
        assert!(
            res(&fr, rev + 800) < 0.3 * peak_f,
            "friction must decay: {} vs {peak_f}",
            res(&fr, rev + 800)
        );
        assert!(
            (res(&bl, rev + 800) - 0.005).abs() < 1e-4,
            "backlash persists at b/2"
        );
        assert!((res(&bl, rev + 1500) - 0.005).abs() < 1e-4);

        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for (truth, expected) in [
            (Truth::Friction(vec![200.0, 200.0]), Effect::CoulombFriction),
            (Truth::Backlash(vec![0.01, 0.006], true), Effect::Backlash),
        ] {
            let meas = measure(&servo, &truth, &cmd, 0.001, 0.0003, &mut rng);
            let block = MotionBlock {
                commanded: cmd.clone(),
                measured: meas,
            };
            let d = diagnose_motion(
                &names(),
                &servo,
                0.001,
                &block,
                None,
                &MotionOptions::default(),
            )
            .unwrap();
            assert_eq!(
                d.verdict,
                expected,
                "{:?}",
                d.effects
                    .iter()
                    .map(|e| (e.fitted.effect(), e.score))
                    .collect::<Vec<_>>()
            );
            assert!(d.gap_after.rms < 0.5 * d.gap_before.rms);
            // the gap sits in the spans that begin at reversals
            let at_reversals: f64 = d
                .spans
                .iter()
                .filter(|s| s.label.contains("reversal"))
                .map(|s| s.share)
                .sum();
            assert!(at_reversals > 0.7, "{:?}", d.spans);
            if expected == Effect::CoulombFriction {
                assert!(d.spans[0].label.contains("reversal"), "{:?}", d.spans[0]);
            }
        }
    }

    #[test]
    fn none_when_the_stored_model_is_right_and_validation_is_passed_through() {
        let servo = servo();
        let cmd = circle(-1.0);
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let meas = measure(&servo, &Truth::None, &cmd, 0.001, 0.0004, &mut rng);
        let vcmd = circle(1.0);
        let vmeas = measure(&servo, &Truth::None, &vcmd, 0.001, 0.0004, &mut rng);
        let main = MotionBlock {
            commanded: cmd,
            measured: meas,
        };
        let val = MotionBlock {
            commanded: vcmd.clone(),
            measured: vmeas,
        };
        let d = diagnose_motion(
            &names(),
            &servo,
            0.001,
            &main,
            Some(&val),
            &MotionOptions::default(),
        )
        .unwrap();
        assert_eq!(d.verdict, Effect::None);
        assert_eq!(d.gap_after, d.gap_before);
        assert!(
            (d.gap_before.rms - 0.0004 * 2f64.sqrt()).abs() < 0.0001,
            "{:?}",
            d.gap_before
        );
        assert!((d.noise_mm - 0.0004).abs() < 0.0001, "{}", d.noise_mm);
        let v = d.validation.unwrap();
        assert_eq!(v.predicted_before, v.predicted_after);
        assert_eq!(v.predicted_before[0].len(), vcmd[0].len());
        assert_eq!(d.effects.len(), 7);
    }

    #[test]
    fn rejects_bad_shapes_and_values_with_the_field_named() {
        let servo = servo();
        let ok = MotionBlock {
            commanded: vec![vec![0.0; 100]; 2],
            measured: vec![vec![0.0; 100]; 2],
        };
        let run = |b: &MotionBlock, p: f64| {
            diagnose_motion(&names(), &servo, p, b, None, &MotionOptions::default())
        };
        assert!(run(&ok, 0.001).is_ok());
        assert!(matches!(run(&ok, 0.0), Err(Error::Invalid { .. })));
        let mut short = ok.clone();
        short.measured[1].pop();
        assert!(
            matches!(run(&short, 0.001), Err(Error::Shape { field, .. }) if field == "commanded.measured")
        );
        let mut nan = ok.clone();
        nan.measured[0][7] = f64::NAN;
        assert!(matches!(
            run(&nan, 0.001),
            Err(Error::NonFinite { index: 7, .. })
        ));
        let tiny = MotionBlock {
            commanded: vec![vec![0.0; 5]; 2],
            measured: vec![vec![0.0; 5]; 2],
        };
        assert!(matches!(run(&tiny, 0.001), Err(Error::Shape { .. })));
        let bad_servo = vec![ServoAxis::first_order(-3.0, 0.0), servo[1].clone()];
        assert!(matches!(
            diagnose_motion(&names(), &bad_servo, 0.001, &ok, None, &MotionOptions::default()),
            Err(Error::Servo { axis, .. }) if axis == "X"
        ));
    }
}
