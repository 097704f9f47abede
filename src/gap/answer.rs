//! The answers of a gap diagnosis (motion and part; openapi.yaml
//! `POST /v1/machines/{machine}/gap-diagnosis`) as JSON: gap before and after,
//! where, the effects with their parameters and scores, the verdict, the validation.

use serde_json::{Map, Value, json};

use super::motion::MotionDiagnosis;
use super::part::PartDiagnosis;

fn params_json(params: &[(String, f64)]) -> Value {
    Value::Object(
        params
            .iter()
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect::<Map<_, _>>(),
    )
}

fn columns_to_rows(cols: &[Vec<f64>]) -> Value {
    let n = cols.first().map_or(0, Vec::len);
    Value::Array(
        (0..n)
            .map(|i| Value::Array(cols.iter().map(|c| json!(c[i])).collect()))
            .collect(),
    )
}

/// The openapi.yaml answer of a motion diagnosis (plus `domain`, `axes`, `noise_mm`).
pub fn motion_answer(axes: &[String], d: &MotionDiagnosis) -> Value {
    let mut out = json!({
        "domain": "motion",
        "axes": axes,
        "gap_before": d.gap_before,
        "where": d.spans,
        "effects": d.effects.iter().map(|e| {
            let mut o = json!({
                "effect": e.fitted.effect().name(),
                "params": params_json(&e.params),
                "score": e.score,
            });
            if !e.at_bound.is_empty() {
                o["at_bound"] = json!(e.at_bound);
            }
            if !e.warnings.is_empty() {
                o["warnings"] = json!(e.warnings);
            }
            o
        }).collect::<Vec<_>>(),
        "verdict": d.verdict.name(),
        "gap_after": d.gap_after,
        "steps": d.steps.iter().map(|s| {
            let mut o = json!({
                "effect": s.fitted.effect().name(),
                "params": params_json(&s.params),
                "gap_after": s.gap_after,
                "score": s.score,
            });
            if !s.warnings.is_empty() {
                o["warnings"] = json!(s.warnings);
            }
            o
        }).collect::<Vec<_>>(),
        "unexplained": {
            "rms": d.unexplained.rms,
            "share": d.unexplained.share,
            "heldout_share": d.unexplained.heldout_share,
            "validation_share": d.unexplained.validation_share,
            "periodic": d.unexplained.periodic,
            "patterns": d.unexplained.patterns,
        },
        "noise_mm": d.noise_mm,
    });
    if let Some(v) = &d.validation {
        out["validation"] = json!({
            "predicted_before": columns_to_rows(&v.predicted_before),
            "predicted_after": columns_to_rows(&v.predicted_after),
            "rms_before": v.rms_before,
            "rms_after": v.rms_after,
            "predicted_steps": v.predicted_steps.iter().map(|p| columns_to_rows(p)).collect::<Vec<_>>(),
            "rms_steps": v.rms_steps,
        });
    }
    out
}

/// The openapi.yaml answer of a part diagnosis (plus `domain`, `predicted_source`).
pub fn part_answer(d: &PartDiagnosis, predicted_source: &str) -> Value {
    let mut out = json!({
        "domain": "part",
        "gap_before": d.gap_before,
        "where": d.regions,
        "effects": d.effects.iter().map(|e| json!({
            "effect": e.effect.name(),
            "params": params_json(&e.params),
            "score": e.score,
        })).collect::<Vec<_>>(),
        "verdict": d.verdict.name(),
        "gap_after": d.gap_after,
        "predicted_source": predicted_source,
    });
    if let Some((before, after, rb, ra)) = &d.validation {
        out["validation"] = json!({
            "predicted_before": before, "predicted_after": after,
            "rms_before": rb, "rms_after": ra,
        });
    }
    out
}
