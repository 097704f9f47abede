//! ISO 230-2 and ISO 230-4 evaluations (CONTRACT v1.1, stateless, sync): `POST /v1/iso230-2`
//! (a table or a logged run), `POST /v1/iso230-4` (one circle run, or two for the
//! hysteresis), and `POST /v1/machines/{machine}/iso230-4/simulate`: the predicted ballbar
//! test of a circle program on the machine's servo model, before the machine runs it.
//! The figures are the metrology core's; the bodies are [`crate::wire::iso230`]'s.

use axum::Router;
use axum::extract::State;
use axum::routing::post;
use serde::{Deserialize, Serialize};

use super::AppState;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::lookup::require_machine_def;
use crate::api::id::PathIds;
use crate::metrology::{
    self, PositionTable, PositioningTrace, TraceOptions, circular_hysteresis, evaluate_circle,
    evaluate_table, evaluate_trace,
};
use crate::motion::{DEFAULT_PERIOD_S, Machine, check_period, machine_for_simulation};
use crate::wire::iso230::{
    CircleFigures, Iso2302Answer, Iso2302Request, Iso2304Answer, Iso2304Request,
};

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/iso230-2", post(iso230_2))
        .route("/v1/iso230-4", post(iso230_4))
        .route("/v1/machines/{machine}/iso230-4/simulate", post(simulate))
}

/// Most samples of a logged run answered synchronously.
pub const MAX_TRACE_SAMPLES: usize = 5_000_000;

/// Evaluates a 230-2 body (table or run) on the blocking pool; the one door both the
/// stateless and the storing route go through. Returns the answer and the table evaluated.
pub async fn evaluate_2(
    state: &AppState,
    req: Iso2302Request,
) -> ApiResult<(Iso2302Answer, PositionTable)> {
    use super::ranges::check_lengths;
    check_lengths("targets", req.targets.iter().flatten())?;
    check_lengths("forward", req.forward.iter().flatten().flatten())?;
    check_lengths("backward", req.backward.iter().flatten().flatten())?;
    if let Some(t) = &req.trace {
        check_lengths("trace.commanded", &t.commanded)?;
        check_lengths("trace.measured", &t.measured)?;
    }
    match (req.targets, req.forward, req.backward, req.trace) {
        (Some(targets), Some(forward), Some(backward), None) => {
            let table = PositionTable {
                targets_mm: targets,
                forward_mm: forward,
                backward_mm: backward,
            };
            let axis = evaluate_table(&table)?;
            Ok((Iso2302Answer::from_axis(&axis), table))
        }
        (None, None, None, Some(t)) => {
            if t.commanded.len() > MAX_TRACE_SAMPLES {
                return Err(ApiError::payload_too_large(format!(
                    "trace has {} samples; at most {MAX_TRACE_SAMPLES} are evaluated at once: \
                     send the run of one axis, or evaluate its table",
                    t.commanded.len()
                )));
            }
            let defaults = TraceOptions::default();
            let opts = TraceOptions {
                min_dwell_s: t.min_dwell_s.unwrap_or(defaults.min_dwell_s),
                target_tolerance_mm: t
                    .target_tolerance_mm
                    .unwrap_or(defaults.target_tolerance_mm),
                settle_speed_mm_s: t.settle_speed_mm_s.unwrap_or(defaults.settle_speed_mm_s),
                min_settled_s: t.min_settled_s.unwrap_or(defaults.min_settled_s),
            };
            let period_s = t.period_s;
            let trace = PositioningTrace {
                period_s: t.period_s,
                commanded_mm: t.commanded,
                measured_mm: t.measured,
            };
            let ev = state
                .jobs
                .run(move || evaluate_trace(&trace, &opts))
                .await??;
            Ok((Iso2302Answer::from_trace(&ev, period_s), ev.table))
        }
        _ => Err(ApiError::bad_request(
            "send either the table {\"targets\": [mm], \"forward\": [[mm per cycle] per target], \
             \"backward\": [[...]]} or a logged run {\"trace\": {\"period_s\": s, \"commanded\": \
             [mm], \"measured\": [mm]}}, not both",
        )),
    }
}

async fn iso230_2(
    State(state): State<AppState>,
    ApiJson(req): ApiJson<Iso2302Request>,
) -> ApiResult<ApiJson<Iso2302Answer>> {
    if req.label.is_some() {
        return Err(ApiError::bad_request(
            "label is kept only with a stored run: POST /v1/machines/{machine}/axes/{axis}/iso230-2",
        ));
    }
    Ok(ApiJson(evaluate_2(&state, req).await?.0))
}

/// Refuses circle points and a centre outside ±100 m and a nominal radius outside
/// (0, 100 m], naming the field: beyond them the figures overflow.
fn check_circle(req: &Iso2304Request) -> ApiResult<()> {
    use super::ranges::{COORD_LIMIT_MM, check_lengths};
    check_lengths("points", req.points.iter().flatten())?;
    check_lengths(
        "reverse_points",
        req.reverse_points.iter().flatten().flatten(),
    )?;
    check_lengths("centre", req.centre.iter().flatten())?;
    if req.radius.is_finite() && !(req.radius > 0.0 && req.radius <= COORD_LIMIT_MM) {
        return Err(ApiError::bad_request(format!(
            "radius is {}; the nominal radius must be a number of mm in (0, {COORD_LIMIT_MM}]",
            req.radius
        )));
    }
    Ok(())
}

async fn iso230_4(
    State(state): State<AppState>,
    ApiJson(req): ApiJson<Iso2304Request>,
) -> ApiResult<ApiJson<Iso2304Answer>> {
    check_circle(&req)?;
    let answer = state
        .jobs
        .run(move || -> Result<Iso2304Answer, metrology::Error> {
            let first = evaluate_circle(&req.points, req.radius, req.centre)?;
            match &req.reverse_points {
                None => Ok(Iso2304Answer::new(&first, None)),
                Some(rev) => {
                    let second = evaluate_circle(rev, req.radius, req.centre)
                        .map_err(|e| rename_points(e, "reverse_points"))?;
                    let h = circular_hysteresis(&req.points, rev, req.centre)?;
                    Ok(Iso2304Answer::new(&first, Some((&second, &h))))
                }
            }
        })
        .await??;
    let figures = [answer.G, answer.F_max, answer.F_min, answer.radius_fit];
    if !figures
        .iter()
        .chain(&answer.centre)
        .chain(&answer.radial_deviation)
        .all(|v| v.is_finite())
    {
        return Err(ApiError::unprocessable(
            "these points do not determine a circle (its figures are not finite numbers): send \
             points spread around the circle, in mm",
        ));
    }
    Ok(ApiJson(answer))
}

fn rename_points(e: metrology::Error, field: &'static str) -> metrology::Error {
    match e {
        metrology::Error::NonFinite { index, .. } => metrology::Error::NonFinite {
            field: field.into(),
            index,
        },
        metrology::Error::Degenerate { reason, .. } => {
            metrology::Error::Degenerate { field, reason }
        }
        other => other,
    }
}

/// Body of the simulated circular test.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulateRequest {
    /// Nominal radius, mm.
    pub radius: f64,
    /// Circle centre [x, y], mm (default [0, 0]).
    #[serde(default)]
    pub centre: Option<[f64; 2]>,
    /// Feed, mm/min (default 1000). Not used with `gcode`.
    #[serde(default)]
    pub feed: Option<f64>,
    /// Height of the circle, mm (default 0). Not used with `gcode`.
    #[serde(default)]
    pub z: Option<f64>,
    /// Directions to run, `"ccw"` and/or `"cw"` (default both). Not used with `gcode`.
    #[serde(default)]
    pub directions: Option<Vec<String>>,
    /// Interpolation period, s (default 0.001).
    #[serde(default)]
    pub period_s: Option<f64>,
    /// A circle program of one's own instead: its moving lines whose command stays on the
    /// nominal circle are evaluated.
    #[serde(default)]
    pub gcode: Option<String>,
    /// `"stored"` (default): simulate with the effects stored with the machine; `"none"`:
    /// with its servo model alone.
    #[serde(default)]
    pub effects: Option<String>,
}

/// One simulated run.
#[derive(Debug, Serialize)]
pub struct SimulatedRun {
    /// The ISO 230-4 figures of the simulated path, mm.
    #[serde(flatten)]
    pub figures: CircleFigures,
    /// The program simulated.
    pub gcode: String,
    /// The evaluated simulated points [x, y], mm (at most 3600, evenly thinned).
    pub points: Vec<[f64; 2]>,
    /// Radial deviation from the nominal radius at those points, mm.
    pub radial_deviation: Vec<f64>,
}

/// The answer of the simulated circular test.
#[derive(Debug, Serialize)]
#[allow(non_snake_case)]
pub struct SimulateAnswer {
    /// Runs by direction (`ccw`, `cw`) or `program`.
    pub runs: std::collections::BTreeMap<String, SimulatedRun>,
    /// Circular hysteresis H between the CW and CCW runs, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub H: Option<f64>,
    /// The standard the figures follow.
    pub standard: &'static str,
    /// How the runs were made.
    pub note: &'static str,
    /// The version of the machine's stored effects the simulation included (null: none).
    pub effects_version: Option<i64>,
}

const SIM_NOTE: &str = "generated runs are three turns (lead-in, data capture, lead-out) from a \
    settled start; the middle turn is evaluated, as a ballbar's data-capture arc";

/// The circle program: rapid to the start on +x of the centre, a 0.5 s dwell, three full
/// turns in the direction asked (G2 = cw, G3 = ccw); the middle turn is line
/// [`MIDDLE_TURN_LINE`].
const MIDDLE_TURN_LINE: u32 = 5;

fn circle_program(c: [f64; 2], radius: f64, z: f64, feed: f64, cw: bool) -> String {
    let (x, y) = (c[0] + radius, c[1]);
    let g = if cw { "G2" } else { "G3" };
    let turn = format!("{g} X{x:.6} Y{y:.6} I{:.6} J0", -radius);
    format!("G90 G17 G21\nG0 X{x:.6} Y{y:.6} Z{z:.6}\nG4 P500\n{turn} F{feed}\n{turn}\n{turn}\n")
}

/// The simulated tool-tip points [x, y] of the evaluated samples: with `middle_line`, the
/// samples of that line; else every line that moves and whose command stays within 1 µm of
/// the nominal circle.
fn ballbar_points(
    m: &Machine,
    p: &crate::motion::ContourPrediction,
    c: [f64; 2],
    radius: f64,
    middle_line: Option<u32>,
) -> ApiResult<Vec<[f64; 2]>> {
    let col = |name: &str| m.axes.iter().position(|a| a.name == name);
    let (Some(ix), Some(iy)) = (col("X"), col("Y")) else {
        return Err(ApiError::unprocessable(
            "the machine has no X and Y axes to run a circle in the XY plane",
        ));
    };
    let cmd = &p.commanded.axes;
    let lines = &p.commanded.line;
    let on_circle =
        |k: usize| ((cmd[ix][k] - c[0]).hypot(cmd[iy][k] - c[1]) - radius).abs() <= 1e-3;
    let mut keep = vec![false; lines.len()];
    let mut k = 0;
    while k < lines.len() {
        let mut e = k;
        while e < lines.len() && lines[e] == lines[k] {
            e += 1;
        }
        let ok = match middle_line {
            Some(l) => lines[k] == l,
            None => {
                let moves =
                    (k + 1..e).any(|j| cmd[ix][j] != cmd[ix][k] || cmd[iy][j] != cmd[iy][k]);
                moves && (k..e).all(on_circle)
            }
        };
        keep[k..e].iter_mut().for_each(|v| *v = ok);
        k = e;
    }
    Ok((0..lines.len())
        .filter(|&k| keep[k])
        .map(|k| [p.actual[ix][k], p.actual[iy][k]])
        .collect())
}

/// Largest radius of a generated circular test, mm (a ballbar's longest extension is about
/// 600 mm; a machine's circle interpolation test rarely exceeds a few metres).
const MAX_SIM_RADIUS_MM: f64 = 5_000.0;
/// Largest feed of a generated circular test, mm/min.
const MAX_SIM_FEED_MM_MIN: f64 = 200_000.0;

fn thin(points: &[[f64; 2]], dev: &[f64]) -> (Vec<[f64; 2]>, Vec<f64>) {
    let step = points.len().div_ceil(3600).max(1);
    (
        points.iter().step_by(step).copied().collect(),
        dev.iter().step_by(step).copied().collect(),
    )
}

async fn simulate(
    State(state): State<AppState>,
    PathIds([machine]): PathIds<1>,
    ApiJson(req): ApiJson<SimulateRequest>,
) -> ApiResult<ApiJson<SimulateAnswer>> {
    let def = require_machine_def(&state, &machine).await?;
    let mut m = machine_for_simulation(&machine, &def)?;
    m.effects =
        super::effects::for_simulation(&state, &machine, &def, req.effects.as_deref()).await?;
    let effects_version = m.effects.version();
    let period_s = req.period_s.unwrap_or(DEFAULT_PERIOD_S);
    check_period(period_s)?;
    let centre = req.centre.unwrap_or([0.0, 0.0]);
    let feed = req.feed.unwrap_or(1000.0);
    let z = req.z.unwrap_or(0.0);
    if !(req.radius.is_finite() && req.radius > 0.0 && req.radius <= MAX_SIM_RADIUS_MM) {
        return Err(ApiError::bad_request(format!(
            "radius is {}; a simulated circular test takes a radius in (0, {MAX_SIM_RADIUS_MM}] mm",
            req.radius
        )));
    }
    super::ranges::check_lengths("centre", &centre)?;
    super::ranges::check_lengths("z", [&z])?;
    if !(centre.iter().all(|v| v.is_finite()) && z.is_finite()) {
        return Err(ApiError::bad_request("centre and z must be finite mm"));
    }
    if !(feed.is_finite() && feed > 0.0 && feed <= MAX_SIM_FEED_MM_MIN) {
        return Err(ApiError::bad_request(format!(
            "feed is {feed}; it must be a number of mm/min in (0, {MAX_SIM_FEED_MM_MIN}]"
        )));
    }
    // (name, program, evaluated line)
    let runs: Vec<(String, String, Option<u32>)> = match &req.gcode {
        Some(text) => {
            if req.feed.is_some() || req.z.is_some() || req.directions.is_some() {
                return Err(ApiError::bad_request(
                    "with gcode, feed, z and directions come from the program: leave them out",
                ));
            }
            vec![("program".into(), text.clone(), None)]
        }
        None => {
            let dirs = req
                .directions
                .clone()
                .unwrap_or_else(|| vec!["ccw".into(), "cw".into()]);
            if dirs.is_empty() {
                return Err(ApiError::bad_request(
                    "directions is empty: send [\"ccw\"], [\"cw\"] or both",
                ));
            }
            let mut runs = Vec::new();
            for d in dirs {
                let cw = match d.as_str() {
                    "cw" => true,
                    "ccw" => false,
                    other => {
                        return Err(ApiError::bad_request(format!(
                            "directions: '{other}' is not a direction; use \"ccw\" or \"cw\""
                        )));
                    }
                };
                if runs
                    .iter()
                    .any(|(n, _, _): &(String, String, Option<u32>)| *n == d)
                {
                    return Err(ApiError::bad_request(format!("directions: '{d}' twice")));
                }
                runs.push((
                    d,
                    circle_program(centre, req.radius, z, feed, cw),
                    Some(MIDDLE_TURN_LINE),
                ));
            }
            runs
        }
    };
    let radius = req.radius;
    let answer = state
        .jobs
        .run(move || -> ApiResult<SimulateAnswer> {
            let mut out = std::collections::BTreeMap::new();
            let mut raw = std::collections::BTreeMap::new();
            for (name, gcode, line) in runs {
                let (program, _warnings) =
                    crate::motion::parse_with(&gcode, &crate::motion::ReadOptions::default())?;
                let p = crate::motion::predict_program(
                    &m,
                    &program,
                    period_s,
                    super::contour::MAX_SYNC_PERIODS,
                )?;
                let pts = ballbar_points(&m, &p, centre, radius, line)?;
                let e = evaluate_circle(&pts, radius, None)?;
                let (points, radial_deviation) = thin(&pts, &e.radial_deviation);
                out.insert(
                    name.clone(),
                    SimulatedRun {
                        figures: CircleFigures::from_eval(&e),
                        gcode,
                        points,
                        radial_deviation,
                    },
                );
                raw.insert(name, pts);
            }
            let h = match (raw.get("cw"), raw.get("ccw")) {
                (Some(cw), Some(ccw)) => Some(circular_hysteresis(cw, ccw, None)?.h),
                _ => None,
            };
            Ok(SimulateAnswer {
                runs: out,
                H: h,
                standard: "ISO 230-4:2005",
                note: SIM_NOTE,
                effects_version,
            })
        })
        .await??;
    Ok(ApiJson(answer))
}
