//! The answer of `POST /v1/machines/{machine}/contour-error`, as the server sends it and
//! `truecut contour --output` writes it: openapi.yaml fields first, then extensions (among
//! them `settle`: how long the servo ran on after the command's end). Rows are serialized
//! straight from the prediction's columns (no copies: a million periods a body).

use serde::Serialize;
use serde::ser::{SerializeSeq, Serializer};

use crate::motion::{
    ContourPrediction, Machine, SETTLE_TOLERANCE_DEG, SETTLE_TOLERANCE_MM, Settle, Warning,
};

/// Columns (one `Vec` per axis) written as rows `[[x, y, z, ...], ...]` without copying.
struct Rows<'a>(&'a [Vec<f64>]);

struct Row<'a>(&'a [Vec<f64>], usize);

impl Serialize for Row<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut seq = s.serialize_seq(Some(self.0.len()))?;
        for col in self.0 {
            seq.serialize_element(&col[self.1])?;
        }
        seq.end()
    }
}

impl Serialize for Rows<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let n = self.0.first().map_or(0, Vec::len);
        let mut seq = s.serialize_seq(Some(n))?;
        for i in 0..n {
            seq.serialize_element(&Row(self.0, i))?;
        }
        seq.end()
    }
}

#[derive(Serialize)]
struct Worst {
    index: usize,
    t: f64,
    line: u32,
    contour_error: f64,
}

/// The run-out after the command's end ([`Settle`]), with its sentence.
#[derive(Serialize)]
struct SettleBody {
    settle_s: f64,
    settled: bool,
    command_end_s: f64,
    lag_at_command_end_mm: f64,
    lag_at_last_sample_mm: f64,
    tolerance_mm: f64,
    tolerance_deg: f64,
    note: String,
}

impl SettleBody {
    fn of(s: &Settle) -> Self {
        let note = if s.settle_s == 0.0 {
            format!(
                "the tool was within {} µm of the program's end point when the command ended \
                 (t = {:.4} s): nothing simulated past it",
                SETTLE_TOLERANCE_MM * 1e3,
                s.command_end_s
            )
        } else {
            format!(
                "simulated {:.4} s past the command's end (t = {:.4} s) {}: the tool was {:.4} µm \
                 from the program's end point when the command ended, {:.4} µm at the last sample",
                s.settle_s,
                s.command_end_s,
                if s.settled {
                    format!(
                        "until every axis stayed within {} µm of the end point",
                        SETTLE_TOLERANCE_MM * 1e3
                    )
                } else {
                    "and the servo had not settled (see warnings)".to_string()
                },
                s.lag_at_command_end_mm * 1e3,
                s.lag_at_last_sample_mm * 1e3
            )
        };
        SettleBody {
            settle_s: s.settle_s,
            settled: s.settled,
            command_end_s: s.command_end_s,
            lag_at_command_end_mm: s.lag_at_command_end_mm,
            lag_at_last_sample_mm: s.lag_at_last_sample_mm,
            tolerance_mm: SETTLE_TOLERANCE_MM,
            tolerance_deg: SETTLE_TOLERANCE_DEG,
            note,
        }
    }
}

#[derive(Serialize)]
struct Tracking<'a> {
    max: &'a [f64],
    rms: &'a [f64],
}

/// The answer: openapi.yaml fields first, then extensions (axis names, period, source line per
/// sample, worst sample, per-axis tracking error, 5-axis orientation error).
#[derive(Serialize)]
struct Answer<'a> {
    warnings: Vec<String>,
    t: &'a [f64],
    commanded: Rows<'a>,
    actual: Rows<'a>,
    contour_error: &'a [f64],
    max: f64,
    rms: f64,
    axes: Vec<&'static str>,
    period_s: f64,
    duration_s: f64,
    line: &'a [u32],
    worst: Worst,
    tracking_error: Tracking<'a>,
    #[serde(skip_serializing_if = "Option::is_none")]
    orientation_error_deg: Option<&'a [f64]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    orientation_max_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    settle: Option<SettleBody>,
    /// The version of the machine's stored effects the simulation included (null: none).
    effects_version: Option<i64>,
}

/// Encodes a prediction of machine `m` as the route's JSON answer (no reader warnings, no
/// run-out).
pub fn encode_answer(m: &Machine, p: &ContourPrediction) -> serde_json::Result<Vec<u8>> {
    encode_answer_with_warnings(m, p, &[], None)
}

/// Encodes a prediction of machine `m` as the route's JSON answer, with the G-code reader's
/// `warnings` (each as "line N: word: message") and the run-out after the command's end
/// (`settle`, from [`crate::motion::predict_program_settled`]; its warning when the servo did
/// not settle).
pub fn encode_answer_with_warnings(
    m: &Machine,
    p: &ContourPrediction,
    warnings: &[Warning],
    settle: Option<&Settle>,
) -> serde_json::Result<Vec<u8>> {
    let ce = &p.report.contour_error;
    let index = ce
        .iter()
        .enumerate()
        .fold(0, |b, (i, v)| if *v > ce[b] { i } else { b });
    let answer = Answer {
        warnings: warnings
            .iter()
            .map(ToString::to_string)
            .chain(settle.and_then(Settle::warning))
            .collect(),
        t: &p.commanded.t,
        commanded: Rows(&p.commanded.axes),
        actual: Rows(&p.actual),
        contour_error: ce,
        max: p.report.max,
        rms: p.report.rms,
        axes: m.axes.iter().map(|a| a.name).collect(),
        period_s: p.commanded.period_s,
        duration_s: p.commanded.t.last().copied().unwrap_or(0.0),
        line: &p.commanded.line,
        worst: Worst {
            index,
            t: p.commanded.t.get(index).copied().unwrap_or(0.0),
            line: p.commanded.line.get(index).copied().unwrap_or(0),
            contour_error: ce.get(index).copied().unwrap_or(0.0),
        },
        tracking_error: Tracking {
            max: &p.report.tracking_max,
            rms: &p.report.tracking_rms,
        },
        orientation_error_deg: p.report.orientation_error_deg.as_deref(),
        orientation_max_deg: p.report.orientation_max_deg,
        settle: settle.map(SettleBody::of),
        effects_version: m.effects.version(),
    };
    let mut out = Vec::with_capacity(ce.len() * 120);
    serde_json::to_writer(&mut out, &answer)?;
    Ok(out)
}
