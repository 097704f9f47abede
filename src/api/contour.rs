//! Contour error from G-code: `POST /v1/machines/{machine}/contour-error` (CONTRACT
//! "Contour error"; seed 003). Also the one `From<motion::Error> for ApiError`.

use axum::Router;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use serde::ser::{SerializeSeq, Serializer};
use serde::{Deserialize, Serialize};

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::lookup::require_machine;
use crate::motion::{ContourPrediction, DEFAULT_PERIOD_S, Machine, predict_contour_error};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/v1/machines/{machine}/contour-error", post(contour_error))
}

/// Most interpolation periods answered synchronously (CONTRACT: sync up to 1,000,000).
pub const MAX_SYNC_PERIODS: usize = 1_000_000;

/// Body of the route.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContourRequest {
    /// The program text (ISO 6983 / Fanuc subset, Sinumerik TRAORI/TRAFOOF).
    pub gcode: String,
    /// Interpolation period, s (default 0.001).
    #[serde(default)]
    pub period_s: Option<f64>,
}

/// Validates `period_s` (s) at the edge: finite, 1e-5..0.1.
pub fn check_period(period_s: f64) -> ApiResult<()> {
    if period_s.is_finite() && (1e-5..=0.1).contains(&period_s) {
        Ok(())
    } else {
        Err(ApiError::bad_request(format!(
            "period_s must be a number of seconds between 0.00001 and 0.1 (default 0.001), got {period_s}"
        )))
    }
}

/// Parses a stored machine definition for simulation, with a 422 naming what to fix.
pub fn machine_for_simulation(id: &str, def: &serde_json::Value) -> ApiResult<Machine> {
    Machine::from_json(def).map_err(|e| {
        ApiError::unprocessable(format!(
            "machine '{id}' cannot be simulated: {e}. Fix it with PUT /v1/machines/{id}"
        ))
    })
}

async fn contour_error(
    State(state): State<AppState>,
    Path(machine): Path<String>,
    ApiJson(req): ApiJson<ContourRequest>,
) -> ApiResult<Response> {
    let def = require_machine(&state, &machine).await?;
    let period_s = req.period_s.unwrap_or(DEFAULT_PERIOD_S);
    check_period(period_s)?;
    if req.gcode.trim().is_empty() {
        return Err(ApiError::bad_request(
            "gcode is empty: send the program text, e.g. \"G1 X10 F600\"",
        ));
    }
    let m = machine_for_simulation(&machine, &def)?;
    let body = state
        .jobs
        .run(move || {
            predict_contour_error(&m, &req.gcode, period_s, MAX_SYNC_PERIODS)
                .map(|p| encode_answer(&m, &p))
        })
        .await??
        .map_err(ApiError::internal)?;
    Ok(([(header::CONTENT_TYPE, "application/json")], body).into_response())
}

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

#[derive(Serialize)]
struct Tracking<'a> {
    max: &'a [f64],
    rms: &'a [f64],
}

/// The answer: CONTRACT fields first, then extensions (axis names, period, source line per
/// sample, worst sample, per-axis tracking error, 5-axis orientation error).
#[derive(Serialize)]
struct Answer<'a> {
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
}

/// Encodes a prediction as the route's JSON answer (also used by `truecut contour --output`).
pub fn encode_answer(m: &Machine, p: &ContourPrediction) -> serde_json::Result<Vec<u8>> {
    let ce = &p.report.contour_error;
    let index = ce
        .iter()
        .enumerate()
        .fold(0, |b, (i, v)| if *v > ce[b] { i } else { b });
    let answer = Answer {
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
    };
    let mut out = Vec::with_capacity(ce.len() * 120);
    serde_json::to_writer(&mut out, &answer)?;
    Ok(out)
}
