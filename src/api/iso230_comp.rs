//! The pitch-error compensation table of an axis from an ISO 230-2 run, in the files
//! controllers load: `GET /v1/machines/{machine}/axes/{axis}/iso230-2/compensation` (from a
//! stored run, the latest by default) and `POST /v1/iso230-2/compensation` (from the body of
//! `POST /v1/iso230-2`, stateless). Query: `format=json|linuxcnc|csv`, `mode=mean|model`,
//! with `mode=model` `spacing_mm`, `cyclic_pitch_mm` or `fit_cyclic=true`, and `reference_mm`
//! (the target the corrections are counted from; default the first target approached in the
//! positive direction: the first forward reading of a logged run, the lowest target of a
//! table). The table and the files are the metrology core's
//! ([`crate::metrology::comp_table`], `comp_format`).

use std::collections::HashMap;

use axum::Router;
use axum::extract::{Query, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Deserialize;

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::id::{Id, PathIds};
use super::iso230::evaluate_2;
use super::iso230_runs::check_axis;
use super::lookup::require_machine;
use crate::metrology::{
    self, CompTable, Cyclic, PositionTable, Reference, TableSource, build_table, csv_file,
    evaluate_table, linuxcnc_file,
};
use crate::wire::iso230::{Iso2302Request, UsedReading};
use crate::wire::iso230_comp::CompTableAnswer;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v1/machines/{machine}/axes/{axis}/iso230-2/compensation",
            get(stored_table),
        )
        .route("/v1/iso230-2/compensation", post(posted_table))
}

/// The file asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Json,
    LinuxCnc,
    Csv,
}

/// The checked query: format, what the table is built from, and the run (GET only).
struct Ask {
    format: Format,
    mode: &'static str,
    source: TableSource,
    run: Option<String>,
    reference_mm: Option<f64>,
}

fn parse_number(q: &HashMap<String, String>, field: &str) -> ApiResult<Option<f64>> {
    q.get(field)
        .map(|v| {
            v.trim().parse::<f64>().map_err(|_| {
                ApiError::bad_request(format!(
                    "query parameter {field}='{v}' must be a number of mm"
                ))
            })
        })
        .transpose()
}

/// Parses the query at the door: unknown parameters, values and combinations are 400.
fn parse_ask(q: &HashMap<String, String>, stored: bool) -> ApiResult<Ask> {
    let known: &[&str] = if stored {
        &[
            "run",
            "format",
            "mode",
            "spacing_mm",
            "cyclic_pitch_mm",
            "fit_cyclic",
            "reference_mm",
        ]
    } else {
        &[
            "format",
            "mode",
            "spacing_mm",
            "cyclic_pitch_mm",
            "fit_cyclic",
            "reference_mm",
        ]
    };
    if let Some(k) = q.keys().find(|k| !known.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown query parameter '{k}'; use {}",
            known.join(", ")
        )));
    }
    let format = match q.get("format").map(String::as_str) {
        None | Some("json") => Format::Json,
        Some("linuxcnc") => Format::LinuxCnc,
        Some("csv") => Format::Csv,
        Some(other) => {
            return Err(ApiError::bad_request(format!(
                "format '{other}' is not offered; use json, linuxcnc (LinuxCNC COMP_FILE_TYPE 1) or csv"
            )));
        }
    };
    let spacing_mm = parse_number(q, "spacing_mm")?;
    let reference_mm = parse_number(q, "reference_mm")?;
    if let Some(r) = reference_mm {
        if !r.is_finite() {
            return Err(ApiError::bad_request(format!(
                "reference_mm={r} must be a finite number of mm: a target of the run"
            )));
        }
    }
    let pitch = parse_number(q, "cyclic_pitch_mm")?;
    let fit = match q.get("fit_cyclic").map(String::as_str) {
        None | Some("false") => false,
        Some("true") => true,
        Some(other) => {
            return Err(ApiError::bad_request(format!(
                "query parameter fit_cyclic='{other}' must be true or false"
            )));
        }
    };
    let (mode, source) = match q.get("mode").map(String::as_str) {
        None | Some("mean") => {
            if spacing_mm.is_some() || pitch.is_some() || fit {
                return Err(ApiError::bad_request(
                    "spacing_mm, cyclic_pitch_mm and fit_cyclic shape a model table: add \
                     mode=model (mode=mean tabulates the run's own targets)",
                ));
            }
            ("mean", TableSource::Mean)
        }
        Some("model") => {
            let cyclic = match (pitch, fit) {
                (Some(_), true) => {
                    return Err(ApiError::bad_request(
                        "give either cyclic_pitch_mm (a known pitch) or fit_cyclic=true, not both",
                    ));
                }
                (Some(p), false) => Cyclic::Pitch(p),
                (None, true) => Cyclic::Fit,
                (None, false) => Cyclic::Off,
            };
            ("model", TableSource::Model { cyclic, spacing_mm })
        }
        Some(other) => {
            return Err(ApiError::bad_request(format!(
                "mode '{other}' is not a table; use mean (the run's mean deviations per target) \
                 or model (scale, backlash and an optional cyclic term on spacing_mm)"
            )));
        }
    };
    let run = if stored {
        match q.get("run").map(String::as_str) {
            None | Some("latest") => None,
            Some(id) => Some(Id::parse("run", id)?.into_string()),
        }
    } else {
        None
    };
    Ok(Ask {
        format,
        mode,
        source,
        run,
        reference_mm,
    })
}

/// The default reference of a run: the target of its first forward reading when the run was
/// logged (`used`, in time order), else `None` (the core takes the lowest target).
fn first_forward(used: Option<&[UsedReading]>) -> Option<f64> {
    used?
        .iter()
        .find(|u| u.direction == "fwd")
        .map(|u| u.target)
}

/// Builds the table and its figures before and after on the blocking pool, and answers it
/// in the asked format; `notes` head the file (provenance), `stem` names it; `first_forward`
/// is the target of a logged run's first forward reading.
async fn answer(
    state: &AppState,
    ask: Ask,
    table: PositionTable,
    first_forward: Option<f64>,
    notes: Vec<String>,
    stem: String,
    run: Option<String>,
) -> ApiResult<Response> {
    let Ask {
        format,
        mode,
        source,
        reference_mm,
        ..
    } = ask;
    let built = state
        .jobs
        .run(
            move || -> Result<(CompTable, Vec<String>, CompTableAnswer), metrology::Error> {
                let axis = evaluate_table(&table)?;
                let reference = match (reference_mm, first_forward) {
                    (Some(p), _) => Reference::Named(p),
                    (None, Some(p)) => Reference::FirstForward(p),
                    (None, None) => Reference::first_forward_of(&axis),
                };
                let comp = build_table(&axis, source, reference)?;
                let (before, after) = comp.predict(&table)?;
                let mut notes = notes;
                notes.push(format!(
                    "predicted on this run's own readings (each plus its correction): E {:.2} -> \
                 {:.2} um, M {:.2} -> {:.2} um",
                    before.e * 1e3,
                    after.e * 1e3,
                    before.m * 1e3,
                    after.m * 1e3
                ));
                let body = CompTableAnswer::new(mode, &comp, &before, &after, run);
                Ok((comp, notes, body))
            },
        )
        .await??;
    let (comp, notes, body) = built;
    let (text, kind, ext) = match format {
        Format::Json => return Ok(ApiJson(body).into_response()),
        Format::LinuxCnc => (
            linuxcnc_file(&comp, &notes)?,
            "text/plain; charset=utf-8",
            "txt",
        ),
        Format::Csv => (csv_file(&comp, &notes), "text/csv; charset=utf-8", "csv"),
    };
    let disposition = format!("attachment; filename=\"{stem}-{mode}-comp.{ext}\"");
    Ok((
        [
            (header::CONTENT_TYPE, kind.to_string()),
            (header::CONTENT_DISPOSITION, disposition),
        ],
        text,
    )
        .into_response())
}

/// The table evaluated of a stored run (`input` of the run).
#[derive(Deserialize)]
struct StoredInput {
    targets: Vec<f64>,
    forward: Vec<Vec<f64>>,
    backward: Vec<Vec<f64>>,
}

async fn stored_table(
    State(state): State<AppState>,
    PathIds([machine, axis]): PathIds<2>,
    Query(q): Query<HashMap<String, String>>,
) -> ApiResult<Response> {
    check_axis(&axis)?;
    let ask = parse_ask(&q, true)?;
    require_machine(&state, &machine).await?;
    let run = match &ask.run {
        Some(id) => state
            .store
            .get_iso230_run(&machine, &axis, id)
            .await?
            .ok_or_else(|| {
                ApiError::not_found(format!(
                    "ISO 230-2 run '{id}' of axis {axis} (machine '{machine}') does not exist: \
                     GET /v1/machines/{machine}/axes/{axis}/iso230-2 lists the runs"
                ))
            })?,
        None => state
            .store
            .list_iso230_runs(&machine, &axis)
            .await?
            .pop()
            .ok_or_else(|| {
                ApiError::not_found(format!(
                    "axis {axis} of machine '{machine}' has no stored ISO 230-2 run: POST one to \
                     /v1/machines/{machine}/axes/{axis}/iso230-2, or send the readings to \
                     POST /v1/iso230-2/compensation"
                ))
            })?,
    };
    let input: StoredInput =
        serde_json::from_value(run.input.clone()).map_err(ApiError::internal)?;
    // A run stored from a log keeps its readings in time order in its answer.
    let used: Option<Vec<UsedReading>> = run
        .answer
        .get("used")
        .and_then(|u| serde_json::from_value(u.clone()).ok());
    let table = PositionTable {
        targets_mm: input.targets,
        forward_mm: input.forward,
        backward_mm: input.backward,
    };
    let label = run
        .label
        .as_deref()
        .map_or(String::new(), |l| format!(" (label '{l}')"));
    let notes = vec![format!(
        "truecut pitch-error compensation table of machine '{machine}' axis {axis}, from ISO \
         230-2 run {}{label}",
        run.id
    )];
    let stem = format!("{machine}-{axis}");
    let first = first_forward(used.as_deref());
    answer(&state, ask, table, first, notes, stem, Some(run.id)).await
}

async fn posted_table(
    State(state): State<AppState>,
    Query(q): Query<HashMap<String, String>>,
    ApiJson(req): ApiJson<Iso2302Request>,
) -> ApiResult<Response> {
    if req.label.is_some() {
        return Err(ApiError::bad_request(
            "label is kept only with a stored run: POST /v1/machines/{machine}/axes/{axis}/iso230-2",
        ));
    }
    let ask = parse_ask(&q, false)?;
    let (evaluated, table) = evaluate_2(&state, req).await?;
    let notes = vec![
        "truecut pitch-error compensation table from the ISO 230-2 run sent (not stored)".into(),
    ];
    let first = first_forward(evaluated.used.as_deref());
    answer(&state, ask, table, first, notes, "iso230-2".into(), None).await
}
