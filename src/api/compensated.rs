//! Compensated programs for CAM post-processors (openapi.yaml; CONTRACT v1.1 "Compensated
//! programs"): `POST /v1/machines/{machine}/compensated-program` (G-code in, G-code out, JSON
//! or `Accept: text/plain`) and `POST /v1/machines/{machine}/compensated-points` (CL points,
//! JSON or CSV). The compensation is the `cam` core's against the machine's volumetric map.

use std::collections::BTreeMap;
use std::sync::Arc;

use axum::Router;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use serde::{Deserialize, Serialize};

use super::AppState;
use super::contour::{ToolTables, reader_options};
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, decode_json, is_csv_body, read_body};
use super::id::{Id, PathIds};
use super::lookup::require_machine_def;
use super::volumetric::{MAX_POINTS, load_map};
use crate::cam::{self, DEFAULT_TOLERANCE_MM};
use crate::motion::{
    AddedEffects, DEFAULT_PERIOD_S, Effects, ReadOptions, check_period, machine_for_simulation,
};
use crate::volumetric::VolumetricMap;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/v1/machines/{machine}/compensated-program",
            post(compensated_program),
        )
        .route(
            "/v1/machines/{machine}/compensated-points",
            post(compensated_points),
        )
}

/// The warning of a request that sent `tool_diameters`.
const DIAMETERS_UNUSED: &str = "tool_diameters: not used here: the program is rewritten on its \
     programmed path, which the controller offsets by the tool radius itself under G41/G42";

/// Header giving the number of warnings of a `text/plain` answer.
pub const WARNINGS_HEADER: &str = "x-truecut-warnings";

/// Kind of the in-process job a `Prefer: respond-async` request runs as.
pub const JOB_KIND: &str = "compensated-program";

/// What a compensation computes: the program and, with `contour`, its figures.
type Work = (cam::Compensated, Option<ContourFigures>);

/// Where a compensation runs: on the worker pool while the request waits, or, when the client
/// asks for a job (`Prefer: respond-async`, RFC 7240), as an in-process job it polls under
/// `/v1/jobs/{id}` (a post-processor's long contour program need not hold a request open).
struct Door<'a> {
    state: &'a AppState,
    job: bool,
    volumetric: bool,
}

/// A compensation done while the request waited, or the `202` naming its job.
enum Outcome {
    Done(cam::Compensated, Option<ContourFigures>),
    Accepted(Response),
}

impl<'a> Door<'a> {
    fn new(state: &'a AppState, headers: &HeaderMap, volumetric: bool) -> Self {
        let job = headers
            .get_all("prefer")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(','))
            .any(|p| p.trim().eq_ignore_ascii_case("respond-async"));
        Door {
            state,
            job,
            volumetric,
        }
    }

    /// Runs `work`; as a job, its result is the JSON answer (warnings included) and its error
    /// the sentence a 4xx would have carried.
    async fn run(
        self,
        work: impl FnOnce() -> Result<Work, cam::Error> + Send + 'static,
    ) -> ApiResult<Outcome> {
        if !self.job {
            let (out, figures) = self.state.jobs.run(work).await??;
            return Ok(Outcome::Done(out, figures));
        }
        let volumetric = self.volumetric;
        let id = self
            .state
            .jobs
            .submit(JOB_KIND, move |p| {
                p.set(0.01);
                let (out, contour) = work().map_err(|e| ApiError::from(e).detail().to_string())?;
                serde_json::to_value(ProgramResponse {
                    gcode: out.gcode,
                    warnings: out.warnings,
                    max_shift_mm: out.max_shift_mm,
                    blocks: out.blocks,
                    volumetric,
                    source_lines: out.source_lines,
                    contour,
                })
                .map_err(|e| e.to_string())
            })
            .await?;
        Ok(Outcome::Accepted(super::jobs::accepted(&id)))
    }
}

/// Body of `compensated-program`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProgramRequest {
    /// The program text (ISO 6983 / Fanuc subset), in work coordinates.
    pub gcode: String,
    /// Volumetric pre-compensation (default: true when the machine has a map).
    #[serde(default)]
    pub volumetric: Option<bool>,
    /// Contour pre-distortion: corners slowed and their points moved, arcs given a corrected
    /// radius, so that the machine's servo model follows the original path over a set of
    /// models (default false).
    #[serde(default)]
    pub contour: Option<bool>,
    /// Interpolation period of the contour model, s.
    #[serde(default)]
    pub period_s: Option<f64>,
    /// With `contour`: longest duration of the answer as a multiple of the original
    /// program's, 1..=2 (default 1.15): the time the corners may take.
    #[serde(default)]
    pub max_duration_ratio: Option<f64>,
    /// With `contour`: half-width of the tolerance band about the path, mm (default 0.01):
    /// the simulated tool may leave the path towards the material (on both sides without
    /// G41/G42) by at most this much, or by what the original already did.
    #[serde(default)]
    pub band_mm: Option<f64>,
    /// Largest distance of the written path from the compensated path, mm (default 0.001).
    #[serde(default)]
    pub tolerance_mm: Option<f64>,
    /// Refuse (422) every word the reader would pass with a warning (default false).
    #[serde(default)]
    pub strict: bool,
    /// Work offsets by code ("G54".."G59"): [x, y, z] mm in machine coordinates.
    #[serde(default)]
    pub work_offsets: BTreeMap<String, [f64; 3]>,
    /// Tool lengths by H number ("1", "2", ...), mm, applied by G43 H.
    #[serde(default)]
    pub tool_lengths: BTreeMap<String, f64>,
    /// Tool diameters by tool number, mm: checked as elsewhere, but the rewrite keeps the
    /// programmed path that the controller offsets itself under G41/G42 (a warning says so).
    #[serde(default)]
    pub tool_diameters: BTreeMap<String, f64>,
    /// Machine home for G28/G30/G53: [x, y, z] mm in machine coordinates.
    #[serde(default)]
    pub home: Option<[f64; 3]>,
    /// With `contour`: `"stored"` (default) simulates with the effects stored with the
    /// machine, `"none"` with its servo model alone.
    #[serde(default)]
    pub effects: Option<String>,
}

impl ProgramRequest {
    fn read_options(&self) -> Result<ReadOptions, ApiError> {
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

/// Answer of `compensated-program` (JSON form).
#[derive(Debug, Serialize)]
pub struct ProgramResponse {
    /// The compensated program.
    pub gcode: String,
    /// Warnings of the reader and the compensation.
    pub warnings: Vec<String>,
    /// Largest |compensation| applied, mm.
    pub max_shift_mm: f64,
    /// Blocks (lines) in the answer.
    pub blocks: usize,
    /// Whether the volumetric pass ran (false: the machine has no map, or it was not asked).
    pub volumetric: bool,
    /// 1-based source line of every output line.
    pub source_lines: Vec<usize>,
    /// With `contour`: the simulated contour error against the original path, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contour: Option<ContourFigures>,
}

/// Contour error of the service's simulation against the original program's path, before
/// (the original program) and after (the returned program), mm.
#[derive(Debug, Serialize)]
pub struct ContourFigures {
    /// RMS distance of the simulated tool tip to the original path, original program, mm.
    pub original_rms_mm: f64,
    /// Max distance, original program, mm.
    pub original_max_mm: f64,
    /// RMS distance with the returned program, mm.
    pub compensated_rms_mm: f64,
    /// Max distance with the returned program, mm.
    pub compensated_max_mm: f64,
    /// Distance-weighted RMS (each period weighted by the path it covers), original, mm.
    pub original_rms_distance_mm: f64,
    /// Distance-weighted RMS with the returned program, mm.
    pub compensated_rms_distance_mm: f64,
    /// Duration of the returned program over the original's (nominal model).
    pub duration_ratio: f64,
    /// Optimiser iterations taken.
    pub iterations: usize,
    /// The returned program on every model of the set (nominal first): ratios to the
    /// original on the same model.
    pub models: Vec<ModelRatios>,
    /// The version of the machine's stored effects every model included (null: none).
    pub effects_version: Option<i64>,
}

/// How the returned program does on one model of the set.
#[derive(Debug, Serialize)]
pub struct ModelRatios {
    /// "nominal", "kv -15 %", "kv +15 %", "kff -0.1", "kff +0.1", "period x0.5".
    pub model: String,
    /// Distance-weighted RMS, returned over original.
    pub rms_ratio: f64,
    /// Max distance, returned over original.
    pub max_ratio: f64,
    /// Duration, returned over original.
    pub duration_ratio: f64,
    /// The figures behind the ratios (a ratio of a model on which the original already
    /// follows the path, as kff + 0.1 at kff 0.9 does, compares two nearly-zero figures):
    /// distance-weighted RMS of the original and the returned program, mm.
    pub original_rms_distance_mm: f64,
    /// See `original_rms_distance_mm`.
    pub compensated_rms_distance_mm: f64,
    /// Max distance of the original and the returned program, mm.
    pub original_max_mm: f64,
    /// See `original_max_mm`.
    pub compensated_max_mm: f64,
    /// Largest excursion beyond the band (towards the material) where the original stayed
    /// within it, mm (≤ 0: none).
    pub gouge_mm: f64,
}

/// `a / b`, 1 when both are 0 (nothing to compare).
fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else if a > 0.0 {
        f64::INFINITY
    } else {
        1.0
    }
}

/// The machine's map, or 409 when it has none.
async fn map_for(state: &AppState, machine: &Id) -> ApiResult<VolumetricMap> {
    load_map(state, machine).await?.ok_or_else(|| {
        ApiError::conflict(format!(
            "machine '{machine}' has no volumetric map to compensate against: PUT \
             /v1/machines/{machine}/volumetric-map first"
        ))
    })
}

/// True when the client asks for the program text alone (`Accept: text/plain`).
fn wants_text(headers: &HeaderMap) -> bool {
    headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|a| a.contains("text/plain"))
}

/// The program with the warnings as `( )` comment lines (ASCII) after a leading `%` and
/// program number (Fanuc-style controls read comments anywhere).
fn with_warning_comments(gcode: &str, warnings: &[String]) -> String {
    let eol = if gcode.contains("\r\n") { "\r\n" } else { "\n" };
    let mut lines: Vec<&str> = gcode.lines().collect();
    let mut at = 0;
    while at < lines.len() {
        let t = lines[at].trim_start().to_ascii_uppercase();
        if t.starts_with('%') || t.starts_with('O') || t.starts_with(':') {
            at += 1;
        } else {
            break;
        }
    }
    let mut comments = vec![format!(
        "(TRUECUT COMPENSATION: {} WARNINGS)",
        warnings.len()
    )];
    for w in warnings {
        // Controls read ASCII comments: brackets for parentheses, plain words for symbols.
        let clean: String = w
            .chars()
            .map(|c| match c {
                '(' => "[".to_string(),
                ')' => "]".to_string(),
                ';' => ",".to_string(),
                'µ' => "u".to_string(),
                '±' => "+/-".to_string(),
                '−' => "-".to_string(),
                '×' => "x".to_string(),
                c if c.is_control() => " ".to_string(),
                c if !c.is_ascii() => "?".to_string(),
                c => c.to_string(),
            })
            .collect();
        comments.push(format!("({clean})"));
    }
    let tail = lines.split_off(at);
    let mut out: Vec<&str> = lines;
    out.extend(comments.iter().map(String::as_str));
    out.extend(tail);
    let mut s = out.join(eol);
    if gcode.ends_with('\n') {
        s.push_str(eol);
    }
    s
}

async fn compensated_program(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    headers: HeaderMap,
    ApiJson(req): ApiJson<ProgramRequest>,
) -> ApiResult<Response> {
    let map = load_map(&state, &machine).await?;
    if req.gcode.trim().is_empty() {
        return Err(ApiError::bad_request(
            "gcode is empty: send the program text, e.g. \"G1 X10 F600\"",
        ));
    }
    let tolerance_mm = req.tolerance_mm.unwrap_or(DEFAULT_TOLERANCE_MM);
    cam::check_tolerance(tolerance_mm)?;
    if let Some(p) = req.period_s {
        check_period(p)?;
    }
    let max_duration_ratio = req
        .max_duration_ratio
        .unwrap_or(cam::DEFAULT_MAX_DURATION_RATIO);
    let band_mm = req.band_mm.unwrap_or(cam::DEFAULT_BAND_MM);
    if !(band_mm.is_finite() && cam::predistort::BAND_RANGE_MM.contains(&band_mm)) {
        return Err(ApiError::bad_request(format!(
            "band_mm must be within {}..{} mm (the tolerance band about the path; 0.01 by \
             default), got {band_mm}",
            cam::predistort::BAND_RANGE_MM.start(),
            cam::predistort::BAND_RANGE_MM.end()
        )));
    }
    if !(1.0..=cam::MAX_DURATION_RATIO).contains(&max_duration_ratio) {
        return Err(ApiError::bad_request(format!(
            "max_duration_ratio must be within 1..{} (the compensated program's duration over the \
             original's; 1.15 by default), got {max_duration_ratio}",
            cam::MAX_DURATION_RATIO
        )));
    }
    // The definition's home and G30 position; its errors matter only for a contour.
    let def = require_machine_def(&state, &machine).await;
    let (home, g30) = def.as_ref().map_or((None, None), |d| (d.home, d.g30));
    let mut options = req.read_options()?.with_reference_points(home, g30);
    // The rewrite works on the programmed path: the controller applies G41/G42 itself.
    let diameters_unused = !std::mem::take(&mut options.tool_diameters_mm).is_empty();
    let volumetric = req.volumetric.unwrap_or(map.is_some());
    let contour = req.contour.unwrap_or(false);
    if !volumetric && !contour {
        return Err(ApiError::bad_request(if map.is_some() {
            "nothing to do: both volumetric and contour are false; send \"volumetric\": true \
             or \"contour\": true"
                .to_string()
        } else {
            format!(
                "nothing to do: machine '{machine}' has no volumetric map (so volumetric defaults \
                 to false) and contour is not requested; PUT /v1/machines/{machine}/volumetric-map \
                 or send \"contour\": true"
            )
        }));
    }
    let map = if volumetric {
        Some(match map {
            Some(m) => m,
            None => map_for(&state, &machine).await?,
        })
    } else {
        None
    };
    // With stored effects, the geometric ones (scale, squareness, cyclic error) are corrected
    // in the commanded points as a volumetric map is, backlash by offsets and take-up moves at
    // reversals, and the others (friction, gain, drift) by the contour pass on the servo model
    // (issue 40 item 2); the answer is judged on the machine with all of them.
    let (sim, geometric) = if contour {
        let def = def?;
        let mut m = machine_for_simulation(&machine, &def)?;
        let stored =
            super::effects::for_simulation_set(&state, &machine, &def, req.effects.as_deref())
                .await?;
        let mut geometric = None;
        if let Some((s, _)) = stored {
            let (geo, rest) = s.split_corrected();
            m.effects = Effects(Some(s as Arc<dyn AddedEffects>));
            if !geo.is_empty() {
                geometric = Some((Arc::new(geo), Arc::new(rest)));
            }
        }
        (Some(m), geometric)
    } else {
        super::effects::wants_stored(req.effects.as_deref())?;
        (None, None)
    };
    let effects_version = sim.as_ref().and_then(|m| m.effects.version());
    let period_s = req.period_s.unwrap_or(DEFAULT_PERIOD_S);
    let popts = cam::PredistortOptions {
        period_s,
        max_iterations: cam::MAX_ITERATIONS,
        max_duration_ratio,
        band_mm,
    };
    let outcome = Door::new(&state, &headers, volumetric)
        .run(move || -> Result<_, cam::Error> {
            let note = |mut out: cam::Compensated| {
                if diameters_unused {
                    out.warnings.push(DIAMETERS_UNUSED.to_string());
                }
                out
            };
            let (out, p) = match (&map, sim) {
                (Some(map), None) => {
                    let out = cam::compensate_program(&req.gcode, &options, map, tolerance_mm)?;
                    return Ok((note(out), None));
                }
                (map, Some(machine)) if geometric.is_some() => {
                    let (corrected, rest) = geometric.expect("matched");
                    let job = super::effects_program::Job {
                        gcode: &req.gcode,
                        options: &options,
                        tolerance_mm,
                        opts: &popts,
                    };
                    super::effects_program::corrected(
                        &job,
                        map.as_ref(),
                        &machine,
                        corrected,
                        rest,
                    )?
                }
                (Some(map), Some(machine)) => cam::volumetric_and_contour(
                    &req.gcode,
                    &options,
                    map,
                    tolerance_mm,
                    &machine,
                    &popts,
                )?,
                (None, Some(machine)) => {
                    cam::contour_program(&req.gcode, &options, &machine, &popts)?
                }
                (None, None) => unreachable!("volumetric or contour was checked above"),
            };
            let figures = ContourFigures {
                original_rms_mm: p.original.rms_mm,
                original_max_mm: p.original.max_mm,
                compensated_rms_mm: p.compensated.rms_mm,
                compensated_max_mm: p.compensated.max_mm,
                original_rms_distance_mm: p.original.rms_distance_mm,
                compensated_rms_distance_mm: p.compensated.rms_distance_mm,
                duration_ratio: ratio(p.compensated.duration_s, p.original.duration_s),
                iterations: p.iterations,
                models: p
                    .models
                    .iter()
                    .map(|m| ModelRatios {
                        model: m.model.clone(),
                        rms_ratio: ratio(m.compensated.rms_distance_mm, m.original.rms_distance_mm),
                        max_ratio: ratio(m.compensated.max_mm, m.original.max_mm),
                        duration_ratio: ratio(m.compensated.duration_s, m.original.duration_s),
                        original_rms_distance_mm: m.original.rms_distance_mm,
                        compensated_rms_distance_mm: m.compensated.rms_distance_mm,
                        original_max_mm: m.original.max_mm,
                        compensated_max_mm: m.compensated.max_mm,
                        gouge_mm: m.compensated.gouge_mm,
                    })
                    .collect(),
                effects_version,
            };
            Ok((note(out), Some(figures)))
        })
        .await?;
    let (out, figures) = match outcome {
        Outcome::Done(out, figures) => (out, figures),
        Outcome::Accepted(job) => return Ok(job),
    };
    if wants_text(&headers) {
        let text = with_warning_comments(&out.gcode, &out.warnings);
        let mut resp =
            ([(header::CONTENT_TYPE, "text/plain; charset=utf-8")], text).into_response();
        resp.headers_mut()
            .insert(WARNINGS_HEADER, HeaderValue::from(out.warnings.len()));
        return Ok(resp);
    }
    Ok(ApiJson(ProgramResponse {
        gcode: out.gcode,
        warnings: out.warnings,
        max_shift_mm: out.max_shift_mm,
        blocks: out.blocks,
        volumetric,
        source_lines: out.source_lines,
        contour: figures,
    })
    .into_response())
}

/// JSON body of `compensated-points`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointsRequest {
    /// CL points (tool tip, machine frame), mm.
    pub points: Vec<[f64; 3]>,
}

/// JSON answer of `compensated-points`.
#[derive(Debug, Serialize)]
pub struct PointsResponse {
    /// p − e(p) per point, mm.
    pub points: Vec<[f64; 3]>,
    /// True where the point lies outside the map's box.
    pub out_of_box: Vec<bool>,
    /// Largest |e(p)|, mm.
    pub max_shift_mm: f64,
}

async fn compensated_points(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    req: Request,
) -> ApiResult<Response> {
    let is_csv = is_csv_body(
        req.headers(),
        "application/json ({\"points\": [[x, y, z], ...]}) or text/csv (header x_mm,y_mm,z_mm)",
    )?;
    let body = read_body(req).await?;
    let points = if is_csv {
        let text = std::str::from_utf8(&body)
            .map_err(|_| ApiError::bad_request("the CSV body is not UTF-8 text"))?;
        cam::points_from_csv(text)?
    } else {
        decode_json::<PointsRequest>(&body)?.points
    };
    if points.len() > MAX_POINTS {
        return Err(ApiError::payload_too_large(format!(
            "{} points: at most {MAX_POINTS} per request; split them",
            points.len()
        )));
    }
    let map = map_for(&state, &machine).await?;
    let out = state
        .jobs
        .run(move || cam::compensate_points(&map, &points))
        .await??;
    if is_csv {
        return Ok((
            [(header::CONTENT_TYPE, "text/csv; charset=utf-8")],
            cam::points_to_csv(&out.points),
        )
            .into_response());
    }
    Ok(ApiJson(PointsResponse {
        points: out.points,
        out_of_box: out.out_of_box,
        max_shift_mm: out.max_shift_mm,
    })
    .into_response())
}
