//! Contour error from G-code: `POST /v1/machines/{machine}/contour-error` (openapi.yaml;
//! Zhang & Chen 2025). The simulation is the motion core's, run on past the command's end
//! until the servo settles ([`crate::motion::settle`]); the answer's shape
//! [`crate::wire::contour`]'s (shared with `truecut contour --output`).

use axum::Router;
use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use serde::Deserialize;
use std::collections::BTreeMap;

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::lookup::require_machine_def;
use crate::api::id::PathIds;
use crate::motion::{
    DEFAULT_PERIOD_S, ReadOptions, check_period, machine_for_simulation, parse_modes,
    predict_program_settled,
};
use crate::wire::contour::encode_answer_with_warnings;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/v1/machines/{machine}/contour-error", post(contour_error))
}

/// Most interpolation periods answered synchronously (openapi.yaml: sync up to 1,000,000).
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
    /// Refuse (422) every word the reader would pass with a warning (default false).
    #[serde(default)]
    pub strict: bool,
    /// Work offsets by code ("G54".."G59"): [x, y, z] mm in machine coordinates.
    #[serde(default)]
    pub work_offsets: BTreeMap<String, [f64; 3]>,
    /// Tool lengths by H number ("1", "2", ...), mm, applied by G43 H.
    #[serde(default)]
    pub tool_lengths: BTreeMap<String, f64>,
    /// Tool diameters by tool number ("1", ...), mm: G41/G42 D (or the tool of T.. M6) then
    /// give the tool-centre path, as LinuxCNC offsets it.
    #[serde(default)]
    pub tool_diameters: BTreeMap<String, f64>,
    /// Machine home for G28/G30/G53: [x, y, z] mm in machine coordinates.
    #[serde(default)]
    pub home: Option<[f64; 3]>,
    /// `"stored"` (default): simulate with the effects stored with the machine; `"none"`:
    /// with its servo model alone.
    #[serde(default)]
    pub effects: Option<String>,
}

impl ContourRequest {
    /// The reader's options (see [`reader_options`]).
    pub fn read_options(&self) -> Result<ReadOptions, ApiError> {
        reader_options(
            self.strict,
            &self.work_offsets,
            &ToolTables {
                lengths: &self.tool_lengths,
                diameters: &self.tool_diameters,
            },
            self.home,
        )
    }
}

/// The tool tables of a program-reading request: lengths by H number and diameters by tool
/// number, mm, keyed as JSON keys ("1", "2", ...).
pub struct ToolTables<'a> {
    /// `tool_lengths`.
    pub lengths: &'a BTreeMap<String, f64>,
    /// `tool_diameters`.
    pub diameters: &'a BTreeMap<String, f64>,
}

/// The reader's options from the body fields every program-reading route shares
/// (contour-error, compensated-program, gap-diagnosis with `gcode`), checked once at the
/// door: offset keys G54..G59, tool keys non-negative integers, every number finite (400
/// naming the field otherwise).
pub fn reader_options(
    strict: bool,
    work_offsets: &BTreeMap<String, [f64; 3]>,
    tools: &ToolTables<'_>,
    home: Option<[f64; 3]>,
) -> Result<ReadOptions, ApiError> {
    let finite = |field: String, v: &[f64]| {
        if v.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(ApiError::bad_request(format!(
                "{field}: values must be finite mm"
            )))
        }
    };
    let mut opts = ReadOptions {
        strict,
        home_mm: home,
        ..ReadOptions::default()
    };
    if let Some(h) = &home {
        finite("home".into(), h)?;
    }
    for (key, off) in work_offsets {
        let idx = ["G54", "G55", "G56", "G57", "G58", "G59"]
            .iter()
            .position(|k| k == key)
            .ok_or_else(|| {
                ApiError::bad_request(format!(
                    "work_offsets.{key}: keys are G54, G55, G56, G57, G58 or G59"
                ))
            })?;
        finite(format!("work_offsets.{key}"), off)?;
        opts.work_offsets_mm[idx] = Some(*off);
    }
    for (key, len) in tools.lengths {
        let number: u32 = key.parse().map_err(|_| {
            ApiError::bad_request(format!(
                "tool_lengths.{key}: keys are H numbers such as \"1\""
            ))
        })?;
        finite(format!("tool_lengths.{key}"), &[*len])?;
        opts.tool_lengths_mm.insert(number, *len);
    }
    for (key, d) in tools.diameters {
        let number: u32 = key.parse().map_err(|_| {
            ApiError::bad_request(format!(
                "tool_diameters.{key}: keys are tool (D) numbers such as \"1\""
            ))
        })?;
        finite(format!("tool_diameters.{key}"), &[*d])?;
        opts.tool_diameters_mm.insert(number, *d);
    }
    Ok(opts)
}

async fn contour_error(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    ApiJson(req): ApiJson<ContourRequest>,
) -> ApiResult<Response> {
    let def = require_machine_def(&state, &machine).await?;
    let period_s = req.period_s.unwrap_or(DEFAULT_PERIOD_S);
    check_period(period_s)?;
    if req.gcode.trim().is_empty() {
        return Err(ApiError::bad_request(
            "gcode is empty: send the program text, e.g. \"G1 X10 F600\"",
        ));
    }
    let options = req.read_options()?.with_reference_points(def.home, def.g30);
    let mut m = machine_for_simulation(&machine, &def)?;
    m.effects =
        super::effects::for_simulation(&state, &machine, &def, req.effects.as_deref()).await?;
    let body = state
        .jobs
        .run(move || {
            let (mut program, control, mut warnings) = parse_modes(&req.gcode, &options)?;
            if !options.strict {
                let has = |name: &str| m.axes.iter().any(|a| a.name == name);
                warnings.extend(program.forget_still_rotary_axes(has("A"), has("C")));
            }
            predict_program_settled(&m, &program, &control, period_s, MAX_SYNC_PERIODS)
                .map(|(p, settle)| encode_answer_with_warnings(&m, &p, &warnings, Some(&settle)))
        })
        .await??
        .map_err(ApiError::internal)?;
    Ok(([(header::CONTENT_TYPE, "application/json")], body).into_response())
}
