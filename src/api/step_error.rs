//! Step error of ball-end finishing (CONTRACT "Step error"; seed 000): the exact geometric route,
//! sample generation, training / fine-tuning the network as a job, and prediction from it.
//! Also the one `From<geometry::Error>` and `From<nn::Error>` for `ApiError`.

mod json;
mod number;
mod stream;

use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use futures::StreamExt;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use super::AppState;
use super::auth::RequireAdmin;
use super::error::{ApiError, ApiResult};
use super::extract::{ApiJson, check_id, is_json};
use super::lookup::{require_machine, require_surface};
use crate::geometry::{
    self, HeightSurface, PathPlan, StepError, StepErrorSegment, StepErrorSolver, StepFeatures,
    grid_segments, height_surface_segments,
};
use crate::nn::{self, Activation, Init, Mlp, Regressor, TrainConfig, gather_rows, split_indices};
pub use json::{DecodeError, SegmentBatch, SegmentsBody, decode as decode_json};

/// Model kind under which the network is stored per machine and surface.
pub const MODEL_KIND: &str = "step_error_nn";
/// Segments answered synchronously by the sample routes (the exact route takes any count the
/// body limit lets through; CONTRACT: sync up to 100,000).
pub const MAX_SYNC_SAMPLES: usize = 200_000;

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/v1/step-error", post(exact))
        .route("/v1/step-error/samples", post(samples))
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-samples",
            post(surface_samples),
        )
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-model",
            post(train).get(model_info),
        )
        .route(
            "/v1/machines/{machine}/surfaces/{surface}/step-error-model/predict",
            post(predict),
        )
}

// ---------- lean request decoding ----------

fn check_tool_radius(r: f64) -> ApiResult<()> {
    if r.is_finite() && r > 0.0 && r < 1000.0 {
        Ok(())
    } else {
        Err(ApiError::bad_request(format!(
            "tool_radius must be the ball radius in mm, a finite number in (0, 1000), got {r}"
        )))
    }
}

fn require_json(headers: &HeaderMap) -> ApiResult<()> {
    if is_json(headers) {
        Ok(())
    } else {
        Err(ApiError::unsupported_media_type(
            "send the body with Content-Type: application/json",
        ))
    }
}

/// Decodes `{"tool_radius"?: mm, "segments": [...]}` (see [`json`]: flat buffers, the large
/// bodies on all cores) and checks the radius and that there are segments.
pub fn decode_segments(headers: &HeaderMap, body: &[u8]) -> ApiResult<SegmentsBody> {
    require_json(headers)?;
    if body.is_empty() {
        return Err(empty_body());
    }
    let req = json::decode(body, 0).map_err(|e| ApiError::bad_request(e.0))?;
    check_segments(req)
}

/// The checks after decoding: a radius in range if sent, at least one segment.
fn check_segments(req: SegmentsBody) -> ApiResult<SegmentsBody> {
    if let Some(r) = req.tool_radius {
        check_tool_radius(r)?;
    }
    if req.is_empty() {
        return Err(ApiError::bad_request(
            "segments is empty: send at least one {\"cl\": [...], \"cc\": [...]}",
        ));
    }
    Ok(req)
}

fn empty_body() -> ApiError {
    ApiError::bad_request(
        "the request body is empty; send {\"tool_radius\": mm, \"segments\": [...]}",
    )
}

/// Exact step errors of the segments of `parts` (in order), split over the machine's cores.
pub fn solve_batch(r: f64, parts: &[SegmentBatch]) -> Result<Vec<StepError>, geometry::Error> {
    let n: usize = parts.iter().map(SegmentBatch::len).sum();
    let threads = std::thread::available_parallelism()
        .map(|t| t.get())
        .unwrap_or(1)
        .min(8);
    let per = n.div_ceil(threads).max(2048);
    // Segments `from..to` of the whole batch, across the parts.
    let solve = |from: usize, to: usize| {
        let mut skip = from;
        let segments = parts
            .iter()
            .flat_map(|p| {
                let start = skip.min(p.len());
                skip -= start;
                (start..p.len()).map(move |i| p.get(i))
            })
            .take(to - from);
        StepErrorSolver::default()
            .solve_batch(r, segments)
            .map_err(|e| match e {
                geometry::Error::InSegment { index, source } => geometry::Error::InSegment {
                    index: from + index,
                    source,
                },
                e => e,
            })
    };
    let results: Vec<Result<Vec<StepError>, geometry::Error>> = std::thread::scope(|s| {
        let handles: Vec<_> = (per..n)
            .step_by(per)
            .map(|from| s.spawn(move || solve(from, (from + per).min(n))))
            .collect();
        let mut all = vec![solve(0, per.min(n))];
        all.extend(
            handles
                .into_iter()
                .map(|h| h.join().expect("step-error worker panicked")),
        );
        all
    });
    let mut out = Vec::with_capacity(n);
    for p in results {
        out.extend(p?);
    }
    Ok(out)
}

fn json_response(body: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "application/json")], body).into_response()
}

/// Reads the body into blocks for [`stream::decode_blocks`] as it arrives (one copy of each
/// chunk), refusing more than `max` bytes; returns the number of bytes read.
async fn feed_body(
    body: Body,
    declared: Option<usize>,
    max: usize,
    tx: std::sync::mpsc::Sender<stream::Block>,
) -> ApiResult<usize> {
    let too_large = || {
        ApiError::payload_too_large(format!(
            "the request body has more than {max} bytes, the most this server accepts \
             (see --max-body-bytes); split the segments over several requests"
        ))
    };
    if declared.is_some_and(|d| d > max) {
        return Err(too_large());
    }
    // About 32 blocks a body: the last block's parse is all that is left after the transfer.
    let target = declared.map_or(4 << 20, |d| (d / 32).clamp(256 << 10, 8 << 20));
    let mut cutter = stream::BlockCutter::new(target, tx);
    let mut chunks = body.into_data_stream();
    while let Some(chunk) = chunks.next().await {
        let chunk = chunk.map_err(|e| {
            ApiError::bad_request(format!("the request body could not be read: {e}"))
        })?;
        if cutter.total() + chunk.len() > max {
            return Err(too_large());
        }
        cutter.push(&chunk);
    }
    let total = cutter.total();
    cutter.finish();
    Ok(total)
}

/// Appends `v` as JSON: shortest round-trip digits (ryu), `null` if not finite.
fn push_f64(out: &mut Vec<u8>, buf: &mut ryu::Buffer, v: f64) {
    if v.is_finite() {
        out.extend_from_slice(buf.format_finite(v).as_bytes());
    } else {
        out.extend_from_slice(b"null");
    }
}

/// `{"step_errors": [mm], "inflections": [index], "tool_radius": mm, "unit": "mm"}` written
/// straight into the buffer.
fn encode_exact(r: f64, errs: &[StepError]) -> Vec<u8> {
    let mut out = Vec::with_capacity(errs.len() * 24 + 96);
    let mut f = ryu::Buffer::new();
    let mut n = itoa::Buffer::new();
    out.extend_from_slice(b"{\"step_errors\":[");
    for (i, e) in errs.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        push_f64(&mut out, &mut f, e.error_mm);
    }
    out.extend_from_slice(b"],\"inflections\":[");
    let mut first = true;
    for (i, e) in errs.iter().enumerate() {
        if e.inflection {
            if !first {
                out.push(b',');
            }
            first = false;
            out.extend_from_slice(n.format(i).as_bytes());
        }
    }
    out.extend_from_slice(b"],\"tool_radius\":");
    push_f64(&mut out, &mut f, r);
    out.extend_from_slice(b",\"unit\":\"mm\"}");
    out
}

async fn exact(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Body,
) -> ApiResult<Response> {
    require_json(&headers)?;
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<usize>().ok());
    // Small bodies: one thread (no helper to start for a few segments).
    let threads = if declared.is_some_and(|d| d < 1 << 20) {
        1
    } else {
        0
    };
    let (tx, rx) = std::sync::mpsc::channel();
    // Decoding runs on the worker pool while this task receives the body.
    let work = state.jobs.run(move || -> ApiResult<Option<Vec<u8>>> {
        let Some(req) =
            stream::decode_blocks(rx, threads).map_err(|e| ApiError::bad_request(e.0))?
        else {
            return Ok(None);
        };
        let req = check_segments(req)?;
        let r = req
            .tool_radius
            .ok_or_else(|| ApiError::bad_request("tool_radius (mm) is required"))?;
        let errs = solve_batch(r, &req.parts)?;
        Ok(Some(encode_exact(r, &errs)))
    });
    let (out, received) = tokio::join!(work, feed_body(body, declared, state.max_body_bytes, tx));
    if received? == 0 {
        return Err(empty_body());
    }
    let out = out??.ok_or_else(|| ApiError::internal("the body was read but not decoded"))?;
    Ok(json_response(out))
}

// ---------- sample generation ----------

/// Where samples come from in `POST /v1/step-error/samples`.
#[derive(Debug, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum SampleSurface {
    /// An analytic height function `z = scale * sum(terms) + offset`.
    Height(HeightSurface),
    /// One of the Python study's surfaces 1, 2, 3.
    Reference(u32),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SamplesRequest {
    surface: SampleSurface,
    plan: PathPlan,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SurfaceSamplesRequest {
    plan: PlanWithOptionalRadius,
}

/// A [`PathPlan`] whose radius defaults to the stored surface's `tool_radius`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlanWithOptionalRadius {
    #[serde(default)]
    tool_radius_mm: Option<f64>,
    #[serde(default)]
    step_over_mm: Option<f64>,
    #[serde(default)]
    cl_spacing_mm: Option<f64>,
    #[serde(default)]
    lines: Option<usize>,
    #[serde(default)]
    points_per_line: Option<usize>,
    #[serde(default)]
    cc_points: Option<usize>,
}

impl PlanWithOptionalRadius {
    fn resolve(&self, surface_radius: Option<f64>) -> ApiResult<PathPlan> {
        let r = self.tool_radius_mm.or(surface_radius).ok_or_else(|| {
            ApiError::bad_request(
                "plan.tool_radius_mm is required (the surface has no tool_radius stored)",
            )
        })?;
        check_tool_radius(r)?;
        Ok(PathPlan {
            tool_radius_mm: r,
            step_over_mm: self.step_over_mm,
            cl_spacing_mm: self.cl_spacing_mm,
            lines: self.lines,
            points_per_line: self.points_per_line,
            cc_points: self.cc_points.unwrap_or(20),
        })
    }
}

#[derive(Serialize)]
struct SamplesAnswer<'a> {
    tool_radius: f64,
    segments: &'a [StepErrorSegment],
    step_errors: Vec<f64>,
    convex: Vec<bool>,
    inflections: Vec<usize>,
    unit: &'static str,
}

fn labelled_samples_json(r: f64, segs: Vec<StepErrorSegment>) -> ApiResult<Vec<u8>> {
    if segs.len() > MAX_SYNC_SAMPLES {
        return Err(ApiError::payload_too_large(format!(
            "the plan makes {} segments; this route answers at most {MAX_SYNC_SAMPLES}: raise step_over_mm or cl_spacing_mm",
            segs.len()
        )));
    }
    let errs = geometry::step_errors(r, &segs, 0)?;
    serde_json::to_vec(&SamplesAnswer {
        tool_radius: r,
        segments: &segs,
        step_errors: errs.iter().map(|e| e.error_mm).collect(),
        convex: errs.iter().map(|e| e.convex).collect(),
        inflections: errs
            .iter()
            .enumerate()
            .filter(|(_, e)| e.inflection)
            .map(|(i, _)| i)
            .collect(),
        unit: "mm",
    })
    .map_err(ApiError::internal)
}

async fn samples(
    State(state): State<AppState>,
    ApiJson(req): ApiJson<SamplesRequest>,
) -> ApiResult<Response> {
    check_tool_radius(req.plan.tool_radius_mm)?;
    let surface = match req.surface {
        SampleSurface::Height(h) => h,
        SampleSurface::Reference(id) => HeightSurface::reference(id).ok_or_else(|| {
            ApiError::bad_request(format!(
                "surface.reference must be 1, 2 or 3 (the study's surfaces), got {id}"
            ))
        })?,
    };
    let out = state
        .jobs
        .run(move || {
            let segs = height_surface_segments(&surface, &req.plan)?;
            labelled_samples_json(req.plan.tool_radius_mm, segs)
        })
        .await??;
    Ok(json_response(out))
}

async fn surface_samples(
    State(state): State<AppState>,
    Path((machine, surface)): Path<(String, String)>,
    ApiJson(req): ApiJson<SurfaceSamplesRequest>,
) -> ApiResult<Response> {
    let s = require_surface(&state, &machine, &surface).await?;
    let plan = req.plan.resolve(s.tool_radius)?;
    let out = state
        .jobs
        .run(move || {
            let segs = grid_segments(s.nu, s.nv, &s.points, &s.normals, &plan)?;
            labelled_samples_json(plan.tool_radius_mm, segs)
        })
        .await??;
    Ok(json_response(out))
}

// ---------- the network ----------

/// What is stored beside the weights (the model file's metadata, JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
struct ModelMeta {
    kind: String,
    features: StepFeatures,
    tool_radius_mm: f64,
    hidden: Vec<usize>,
    output_unit: String,
    report: Value,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BaseRef {
    machine: String,
    surface: String,
}

#[derive(Debug, Clone, Copy, Deserialize, Default, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum Preset {
    /// He init, Adam 1e-3 with cosine decay, no dropout, early stopping (converges).
    #[default]
    Default,
    /// The seed's settings: N(0,1) init, SGD lr 1e-5 momentum 0.8, dropout 0.5 (does not converge).
    Paper,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrainRequest {
    #[serde(default)]
    tool_radius: Option<f64>,
    #[serde(default)]
    segments: Option<Vec<StepErrorSegment>>,
    /// Generate labelled samples from the stored nominal grid instead of sending segments.
    #[serde(default)]
    generate: Option<PlanWithOptionalRadius>,
    #[serde(default)]
    base: Option<BaseRef>,
    #[serde(default)]
    hidden: Option<Vec<usize>>,
    #[serde(default)]
    epochs: Option<usize>,
    #[serde(default)]
    preset: Option<Preset>,
    #[serde(default)]
    features: Option<StepFeatures>,
    #[serde(default)]
    learning_rate: Option<f64>,
    #[serde(default)]
    dropout: Option<f64>,
    #[serde(default)]
    batch_size: Option<usize>,
    /// Part of the samples held out to report accuracy (the paper's 30 %).
    #[serde(default)]
    test_fraction: Option<f64>,
    #[serde(default)]
    seed: Option<u64>,
}

fn model_missing(machine: &str, surface: &str) -> ApiError {
    ApiError::not_found(format!(
        "no step-error model for machine '{machine}' surface '{surface}': train one with \
         POST /v1/machines/{machine}/surfaces/{surface}/step-error-model"
    ))
}

async fn load_model(
    state: &AppState,
    machine: &str,
    surface: &str,
) -> ApiResult<(Regressor, ModelMeta)> {
    let bytes = state
        .store
        .models()
        .load(machine, Some(surface), MODEL_KIND)
        .await?
        .ok_or_else(|| model_missing(machine, surface))?;
    let reg = Regressor::from_bytes(&bytes).map_err(ApiError::internal)?;
    let meta: ModelMeta = serde_json::from_str(&reg.metadata).map_err(ApiError::internal)?;
    Ok((reg, meta))
}

async fn train(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    Path((machine, surface)): Path<(String, String)>,
    ApiJson(req): ApiJson<TrainRequest>,
) -> ApiResult<impl IntoResponse> {
    let stored = require_surface(&state, &machine, &surface).await?;
    let base = match &req.base {
        Some(b) => {
            check_id("base.machine", &b.machine)?;
            check_id("base.surface", &b.surface)?;
            Some(load_model(&state, &b.machine, &b.surface).await.map_err(|e| {
                if e.status() == StatusCode::NOT_FOUND {
                    ApiError::not_found(format!(
                        "base model of machine '{}' surface '{}' does not exist: train it first",
                        b.machine, b.surface
                    ))
                } else {
                    e
                }
            })?)
        }
        None => None,
    };
    // Samples: sent, or generated from the stored nominal grid.
    let (r, segments) = match (req.segments, &req.generate) {
        (Some(_), Some(_)) => {
            return Err(ApiError::bad_request(
                "send either segments or generate, not both",
            ));
        }
        (Some(segs), None) => {
            let r = req.tool_radius.or(stored.tool_radius).ok_or_else(|| {
                ApiError::bad_request("tool_radius (mm) is required with segments")
            })?;
            check_tool_radius(r)?;
            if segs.is_empty() {
                return Err(ApiError::bad_request("segments is empty"));
            }
            (r, segs)
        }
        (None, Some(g)) => {
            let plan = g.resolve(req.tool_radius.or(stored.tool_radius))?;
            let segs = grid_segments(stored.nu, stored.nv, &stored.points, &stored.normals, &plan)?;
            (plan.tool_radius_mm, segs)
        }
        (None, None) => {
            return Err(ApiError::bad_request(
                "send segments (with tool_radius) or generate: {\"step_over_mm\": .., \"cl_spacing_mm\": ..} to sample the stored surface",
            ));
        }
    };
    if segments.len() < 10 {
        return Err(ApiError::unprocessable(format!(
            "{} segments are too few to train on: send at least 10",
            segments.len()
        )));
    }
    let preset = req.preset.unwrap_or_default();
    let (features, hidden) = match &base {
        Some((reg, meta)) => {
            if req.hidden.is_some() || req.features.is_some() {
                return Err(ApiError::bad_request(
                    "hidden and features come from the base model when fine-tuning: drop them",
                ));
            }
            let sizes = reg.mlp().sizes();
            (meta.features, sizes[1..sizes.len() - 1].to_vec())
        }
        None => {
            let f = req.features.unwrap_or(StepFeatures {
                two_sided: true,
                ..StepFeatures::local()
            });
            f.validate()?;
            let hidden = req.hidden.clone().unwrap_or_else(|| vec![28, 20]);
            if hidden.is_empty() || hidden.len() > 8 || hidden.iter().any(|&h| h == 0 || h > 1024) {
                return Err(ApiError::bad_request(
                    "hidden must list 1 to 8 layer sizes, each 1..=1024 (default [28, 20])",
                ));
            }
            (f, hidden)
        }
    };
    let mut cfg = match preset {
        Preset::Default => TrainConfig::default(),
        Preset::Paper => TrainConfig::paper(),
    };
    if base.is_some() {
        cfg.epochs = 100;
        cfg.patience = Some(20);
    }
    if let Some(e) = req.epochs {
        if !(1..=20_000).contains(&e) {
            return Err(ApiError::bad_request(format!(
                "epochs must be in 1..=20000, got {e}"
            )));
        }
        cfg.epochs = e;
    }
    if let Some(lr) = req.learning_rate {
        cfg.optimizer = match cfg.optimizer {
            nn::Optimizer::Sgd { momentum, .. } => nn::Optimizer::Sgd { lr, momentum },
            nn::Optimizer::Adam {
                beta1, beta2, eps, ..
            } => nn::Optimizer::Adam {
                lr,
                beta1,
                beta2,
                eps,
            },
        };
    }
    if let Some(d) = req.dropout {
        cfg.dropout = d;
    }
    if let Some(b) = req.batch_size {
        cfg.batch_size = b;
    }
    cfg.seed = req.seed.unwrap_or(0);
    let test_fraction = req.test_fraction.unwrap_or(0.3);
    if !(0.0..=0.9).contains(&test_fraction) {
        return Err(ApiError::bad_request(format!(
            "test_fraction must be in [0, 0.9] (default 0.3), got {test_fraction}"
        )));
    }
    let init = if preset == Preset::Paper {
        Init::StandardNormal
    } else {
        Init::He
    };
    let store = state.store.clone();
    let handle = tokio::runtime::Handle::current();
    let base_name = req
        .base
        .map(|b| json!({"machine": b.machine, "surface": b.surface}));
    let id = state
        .jobs
        .submit("step_error_training", move |progress| {
            let job = TrainJob {
                r,
                features,
                hidden,
                init,
                cfg,
                test_fraction,
                base: base.map(|b| b.0),
                base_name,
            };
            let (reg, result) = job
                .run(&segments, &|p| progress.set(p))
                .map_err(|e| e.detail().to_string())?;
            handle
                .block_on(store.models().save(
                    &machine,
                    Some(&surface),
                    MODEL_KIND,
                    &reg.to_bytes(),
                ))
                .map_err(|e| format!("the model was trained but could not be saved: {e:#}"))?;
            Ok(result)
        })
        .await?;
    Ok((StatusCode::ACCEPTED, ApiJson(json!({"job": id}))))
}

/// The training work, off the async runtime (also used by `truecut step train`).
pub struct TrainJob {
    /// Tool radius of the samples, mm.
    pub r: f64,
    /// Network inputs and outputs (ignored when fine-tuning: the base's are used).
    pub features: StepFeatures,
    /// Hidden layer sizes (ignored when fine-tuning).
    pub hidden: Vec<usize>,
    /// Weight initialisation.
    pub init: Init,
    /// Training hyper-parameters.
    pub cfg: TrainConfig,
    /// Held-out part for the reported test errors (0.3 = the paper's 70/30).
    pub test_fraction: f64,
    /// Model to fine-tune, if any.
    pub base: Option<Regressor>,
    /// How to name the base in the report.
    pub base_name: Option<Value>,
}

/// (max, mean) absolute error, µm.
fn abs_errors(pred: &[f64], truth: &[f64]) -> (f64, f64) {
    let e = pred.iter().zip(truth).map(|(p, t)| (p - t).abs());
    let (mut max, mut sum) = (0.0f64, 0.0);
    for v in e {
        max = max.max(v);
        sum += v;
    }
    (max, sum / truth.len().max(1) as f64)
}

impl TrainJob {
    /// A fresh network with the default inputs ([`StepFeatures::local`], two-sided), hidden
    /// [28, 20], He init and [`TrainConfig::default`].
    pub fn new(tool_radius_mm: f64) -> Self {
        TrainJob {
            r: tool_radius_mm,
            features: StepFeatures {
                two_sided: true,
                ..StepFeatures::local()
            },
            hidden: vec![28, 20],
            init: Init::He,
            cfg: TrainConfig::default(),
            test_fraction: 0.3,
            base: None,
            base_name: None,
        }
    }

    /// Labels `segs` exactly, trains (or fine-tunes the base), and returns the model (metadata
    /// filled) and the report JSON; `progress` receives 0..1.
    pub fn run(
        self,
        segs: &[StepErrorSegment],
        progress: &dyn Fn(f64),
    ) -> ApiResult<(Regressor, Value)> {
        let f = match &self.base {
            Some(b) => serde_json::from_str::<ModelMeta>(&b.metadata)
                .map(|m| m.features)
                .unwrap_or(self.features),
            None => self.features,
        };
        let mut solver = StepErrorSolver::default().both_branches(f.two_sided);
        let exact: Vec<StepError> = segs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                solver
                    .solve(self.r, s.cl, &s.cc)
                    .map_err(|e| geometry::Error::InSegment {
                        index: i,
                        source: Box::new(e),
                    })
            })
            .collect::<Result<_, _>>()?;
        progress(0.05);
        let (x, convex) = f.matrix(self.r, segs.iter().map(|s| (s.cl, &s.cc[..])))?;
        let t: Vec<f64> = exact.iter().flat_map(|e| f.targets(e)).collect();
        let y_um: Vec<f64> = exact.iter().map(|e| e.error_mm * 1000.0).collect();
        let (w, no) = (f.len(), f.n_outputs());
        let (train_idx, test_idx) = split_indices(segs.len(), self.test_fraction, self.cfg.seed);
        let (fit_pos, val_pos) = split_indices(
            train_idx.len(),
            if self.base.is_some() { 0.2 } else { 0.1 },
            self.cfg.seed + 1,
        );
        let pick = |pos: &[usize]| pos.iter().map(|&i| train_idx[i]).collect::<Vec<_>>();
        let (fit, val) = (pick(&fit_pos), pick(&val_pos));
        if fit.is_empty() || val.is_empty() {
            return Err(ApiError::unprocessable(
                "too few segments to split into training and validation parts: send more",
            ));
        }
        let (xf, tf) = (gather_rows(&x, w, &fit), gather_rows(&t, no, &fit));
        let (xv, tv) = (gather_rows(&x, w, &val), gather_rows(&t, no, &val));
        let epochs = self.cfg.epochs as f64;
        let mut on_epoch = |s: &nn::EpochStats| {
            progress(0.05 + 0.9 * s.epoch as f64 / epochs);
            true
        };
        let eval = |reg: &Regressor| -> ApiResult<Option<(f64, f64)>> {
            if test_idx.is_empty() {
                return Ok(None);
            }
            let p = reg.predict(&gather_rows(&x, w, &test_idx))?;
            let c: Vec<bool> = test_idx.iter().map(|&i| convex[i]).collect();
            let truth: Vec<f64> = test_idx.iter().map(|&i| y_um[i]).collect();
            Ok(Some(abs_errors(&f.combine(&p, &c), &truth)))
        };
        let (reg, report, base_test) = match self.base {
            Some(mut reg) => {
                let before = eval(&reg)?;
                let rep = reg.fine_tune(&xf, &tf, Some((&xv, &tv)), &self.cfg, &mut on_epoch)?;
                (reg, rep, before)
            }
            None => {
                let mut sizes = vec![w];
                sizes.extend(&self.hidden);
                sizes.push(no);
                let mlp = Mlp::new(
                    &sizes,
                    Activation::Relu,
                    Activation::Identity,
                    self.init,
                    self.cfg.seed,
                )?;
                let (reg, rep) =
                    Regressor::fit(mlp, &xf, &tf, Some((&xv, &tv)), &self.cfg, &mut on_epoch)?;
                (reg, rep, None)
            }
        };
        let test = eval(&reg)?;
        let result = json!({
            "kind": MODEL_KIND,
            "samples": segs.len(),
            "train": fit.len(),
            "validation": val.len(),
            "test": test_idx.len(),
            "epochs_run": report.train_loss.len(),
            "best_epoch": report.best_epoch,
            "stopped_early": report.stopped_early,
            "best_validation_mse": report.best_val_loss,
            "test_max_abs_um": test.map(|t| t.0),
            "test_mean_abs_um": test.map(|t| t.1),
            "base": self.base_name,
            "base_test_max_abs_um": base_test.map(|t| t.0),
            "base_test_mean_abs_um": base_test.map(|t| t.1),
            "label_max_um": y_um.iter().cloned().fold(0.0, f64::max),
        });
        let meta = ModelMeta {
            kind: MODEL_KIND.into(),
            features: f,
            tool_radius_mm: self.r,
            hidden: reg.mlp().sizes()[1..reg.mlp().sizes().len() - 1].to_vec(),
            output_unit: "um".into(),
            report: result.clone(),
        };
        let mut reg = reg;
        reg.metadata = serde_json::to_string(&meta).map_err(ApiError::internal)?;
        progress(0.97);
        Ok((reg, result))
    }
}

/// Decodes a model file's metadata: (features, training tool radius in mm).
pub fn model_features(reg: &Regressor) -> ApiResult<(StepFeatures, f64)> {
    let meta: ModelMeta = serde_json::from_str(&reg.metadata).map_err(ApiError::internal)?;
    Ok((meta.features, meta.tool_radius_mm))
}

async fn model_info(
    State(state): State<AppState>,
    Path((machine, surface)): Path<(String, String)>,
) -> ApiResult<ApiJson<Value>> {
    require_surface(&state, &machine, &surface).await?;
    let (reg, meta) = load_model(&state, &machine, &surface).await?;
    Ok(ApiJson(json!({
        "machine": machine,
        "surface": surface,
        "kind": MODEL_KIND,
        "layers": reg.mlp().sizes(),
        "features": meta.features,
        "tool_radius_mm": meta.tool_radius_mm,
        "output_unit": meta.output_unit,
        "training": meta.report,
    })))
}

#[derive(Serialize)]
struct PredictAnswer<'a> {
    step_errors: &'a [f64],
    tool_radius: f64,
    unit: &'static str,
    model: &'static str,
}

async fn predict(
    State(state): State<AppState>,
    Path((machine, surface)): Path<(String, String)>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Response> {
    check_id("machine", &machine)?;
    check_id("surface", &surface)?;
    require_machine(&state, &machine).await?;
    require_surface(&state, &machine, &surface).await?;
    let (reg, meta) = load_model(&state, &machine, &surface).await?;
    let out = state
        .jobs
        .run(move || -> ApiResult<Vec<u8>> {
            let req = decode_segments(&headers, &body)?;
            let r = req.tool_radius.unwrap_or(meta.tool_radius_mm);
            let batch = SegmentBatch::concat(req.parts);
            let f = meta.features;
            let (x, convex) = f.matrix(r, batch.iter())?;
            let y = reg.predict_parallel(&x, 0)?;
            let e: Vec<f64> = f
                .combine(&y, &convex)
                .into_iter()
                .map(|v| v / 1000.0)
                .collect();
            serde_json::to_vec(&PredictAnswer {
                step_errors: &e,
                tool_radius: r,
                unit: "mm",
                model: MODEL_KIND,
            })
            .map_err(ApiError::internal)
        })
        .await??;
    Ok(json_response(out))
}
