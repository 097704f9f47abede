//! The step-error network over HTTP: training / fine-tuning as a job
//! (`POST .../step-error-model`), its description (`GET`), and prediction (`POST .../predict`).
//! The recipe is the `step_error` core's ([`TrainJob`]); this file parses the request, loads
//! and saves the model files through `store`.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use super::exact::{check_tool_radius, decode_segments, json_response};
use super::samples::PlanWithOptionalRadius;
use crate::api::AppState;
use crate::api::auth::RequireAdmin;
use crate::api::error::{ApiError, ApiResult};
use crate::api::extract::{ApiJson, decode_json, is_json, read_body};
use crate::api::id::{Id, PathIds};
use crate::api::lookup::{require_machine, require_surface};
use crate::api::model_versions::{self as versions, ModelRef, RollbackRequest};
use crate::geometry::{self, StepErrorSegment, StepFeatures, grid_segments};
use crate::jobs::{Progress, Runner};
use crate::nn::{self, Init, Regressor, TrainConfig};
use crate::step_error::{MODEL_KIND, ModelMeta, SegmentBatch, TrainJob, predict_um};
use crate::store::JobDone;

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
    /// Zhang et al. 2023's settings: N(0,1) init, SGD lr 1e-5 momentum 0.8, dropout 0.5 (does not
    /// converge).
    Paper,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct TrainRequest {
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
    /// Part of the samples held out to report accuracy (Zhang et al. 2023's 30 %).
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
    let meta = ModelMeta::of(&reg)?;
    Ok((reg, meta))
}

/// Kind of the stored training job (input: machine, surface and the request body).
pub const TRAINING_JOB: &str = "step_error_training";

/// Input of a stored training job: where the model goes and the request body as sent.
#[derive(Debug, Serialize, Deserialize)]
struct StoredTraining {
    machine: String,
    surface: String,
    body: String,
}

/// A training request checked and resolved against what is stored: the samples, the
/// network's shape and the recipe.
struct Prepared {
    job: TrainJob,
    segments: Vec<StepErrorSegment>,
}

/// Checks a training request and resolves it against the stored surface (and base model):
/// the door runs it for the 4xx answers, the job runs it again on whichever instance
/// claims it.
async fn prepare(
    state: &AppState,
    machine: &Id,
    surface: &Id,
    req: TrainRequest,
) -> ApiResult<Prepared> {
    let stored = require_surface(state, machine, surface).await?;
    let base = match &req.base {
        Some(b) => {
            Id::parse("base.machine", &b.machine)?;
            Id::parse("base.surface", &b.surface)?;
            Some(load_model(state, &b.machine, &b.surface).await.map_err(|e| {
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
            let f = req.features.unwrap_or_else(StepFeatures::profile);
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
    let base_name = req
        .base
        .map(|b| json!({"machine": b.machine, "surface": b.surface}));
    Ok(Prepared {
        job: TrainJob {
            r,
            features,
            hidden,
            init,
            cfg,
            test_fraction,
            base: base.map(|b| b.0),
            base_name,
        },
        segments,
    })
}

pub(super) async fn train(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine, surface]): PathIds<2>,
    request: Request,
) -> ApiResult<impl IntoResponse> {
    if !is_json(request.headers()) {
        return Err(ApiError::unsupported_media_type(
            "send the body with Content-Type: application/json",
        ));
    }
    let body = read_body(request).await?;
    let req: TrainRequest = decode_json(&body)?;
    prepare(&state, &machine, &surface, req).await?;
    let input = serde_json::to_string(&StoredTraining {
        machine: machine.to_string(),
        surface: surface.to_string(),
        body: String::from_utf8(body.to_vec())
            .map_err(|_| ApiError::bad_request("the request body is not UTF-8 JSON"))?,
    })
    .map_err(ApiError::internal)?;
    let id = state.jobs.enqueue(TRAINING_JOB, input).await?;
    Ok(super::super::jobs::accepted(&id))
}

/// Runs a stored training job on any instance: prepares the request again, trains, and
/// saves the model as a new version in the same transaction that marks the job done.
pub fn training_runner(state: AppState) -> Runner {
    let handle = tokio::runtime::Handle::current();
    Arc::new(move |input: &str, progress: &Progress| {
        // A database outage (503) puts the job back in the queue instead of failing it.
        let sentence = |e: ApiError| {
            if e.status() == axum::http::StatusCode::SERVICE_UNAVAILABLE {
                progress.retry_later();
            }
            e.detail().to_string()
        };
        let stored: StoredTraining = serde_json::from_str(input)
            .map_err(|e| format!("the stored job input is not a training request: {e}"))?;
        let req: TrainRequest = serde_json::from_str(&stored.body)
            .map_err(|e| format!("the stored request is not a training request: {e}"))?;
        let machine = Id::parse("machine", &stored.machine).map_err(sentence)?;
        let surface = Id::parse("surface", &stored.surface).map_err(sentence)?;
        let prepared = handle
            .block_on(prepare(&state, &machine, &surface, req))
            .map_err(sentence)?;
        let (reg, result) = prepared
            .job
            .run(&prepared.segments, &|p| {
                progress.set(p);
                !progress.is_cancelled()
            })
            .map_err(|e| ApiError::from(e).detail().to_string())?;
        // Nothing is stored once a client cancelled the job (DELETE /v1/jobs/{id}).
        progress.commit().map_err(|e| e.to_string())?;
        let id = progress
            .job_id()
            .ok_or("a stored job runs with its id")?
            .to_string();
        handle
            .block_on(state.store.models().save_for_job(
                &machine,
                Some(&surface),
                MODEL_KIND,
                &reg.to_bytes(),
                JobDone {
                    id: &id,
                    result: &result,
                    epoch: progress.epoch(),
                },
            ))
            .map_err(|e| {
                if crate::store::database_outage(&e).is_some() {
                    progress.retry_later();
                }
                format!("the model was trained but could not be saved: {e:#}")
            })?;
        Ok(result)
    })
}

pub(super) async fn model_info(
    State(state): State<AppState>,
    PathIds([machine, surface]): PathIds<2>,
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

fn model_ref<'a>(machine: &'a Id, surface: &'a Id) -> ModelRef<'a> {
    ModelRef {
        machine,
        surface: Some(surface),
        kind: MODEL_KIND,
        path: format!("/v1/machines/{machine}/surfaces/{surface}/step-error-model"),
        made_by: format!("POST /v1/machines/{machine}/surfaces/{surface}/step-error-model"),
    }
}

pub(super) async fn model_versions(
    State(state): State<AppState>,
    PathIds([machine, surface]): PathIds<2>,
) -> ApiResult<ApiJson<Value>> {
    require_surface(&state, &machine, &surface).await?;
    Ok(ApiJson(
        versions::list(&state, &model_ref(&machine, &surface)).await?,
    ))
}

pub(super) async fn model_rollback(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine, surface]): PathIds<2>,
    ApiJson(req): ApiJson<RollbackRequest>,
) -> ApiResult<ApiJson<Value>> {
    require_surface(&state, &machine, &surface).await?;
    Ok(ApiJson(
        versions::rollback(&state, &model_ref(&machine, &surface), req).await?,
    ))
}

/// `DELETE .../step-error-model`: the model and every kept version, from any instance.
pub(super) async fn delete_model(
    State(state): State<AppState>,
    _admin: RequireAdmin,
    PathIds([machine, surface]): PathIds<2>,
) -> ApiResult<StatusCode> {
    require_surface(&state, &machine, &surface).await?;
    if !state
        .store
        .models()
        .delete(&machine, Some(&surface), MODEL_KIND)
        .await?
    {
        return Err(model_missing(&machine, &surface));
    }
    Ok(StatusCode::NO_CONTENT)
}

#[derive(Serialize)]
struct PredictAnswer<'a> {
    step_errors: &'a [f64],
    tool_radius: f64,
    unit: &'static str,
    model: &'static str,
    warnings: Vec<String>,
}

/// Standard deviations from the training mean beyond which a feature is called outside the
/// trained range (a z-score of 4 is outside 99.99 % of a normal sample).
pub const TRAINED_RANGE_Z: f64 = 4.0;

/// A warning naming the segments (first few) with a feature more than [`TRAINED_RANGE_Z`]
/// training standard deviations from the training mean: there the network extrapolates.
/// The model file keeps the z-score scaler of its inputs, not their extremes.
fn outside_training(x: &[f64], scaler: &crate::nn::ZScore) -> Vec<String> {
    let cols = scaler.cols().max(1);
    let outside: Vec<usize> = x
        .chunks_exact(cols)
        .enumerate()
        .filter(|(_, row)| {
            row.iter()
                .zip(scaler.mean.iter().zip(&scaler.std))
                .any(|(v, (m, s))| ((v - m) / s).abs() > TRAINED_RANGE_Z)
        })
        .map(|(i, _)| i)
        .collect();
    if outside.is_empty() {
        return Vec::new();
    }
    let shown: Vec<String> = outside.iter().take(10).map(|i| i.to_string()).collect();
    vec![format!(
        "{} segment(s) lie outside the range the network was trained on (a feature more than \
         {TRAINED_RANGE_Z} standard deviations from its training mean): segments {}{}. Their \
         predictions are extrapolations; compute them with POST /v1/step-error or train on \
         such segments",
        outside.len(),
        shown.join(", "),
        if outside.len() > 10 { ", ..." } else { "" }
    )]
}

pub(super) async fn predict(
    State(state): State<AppState>,
    PathIds([machine, surface]): PathIds<2>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Response> {
    require_machine(&state, &machine).await?;
    require_surface(&state, &machine, &surface).await?;
    let (reg, meta) = load_model(&state, &machine, &surface).await?;
    let out = state
        .jobs
        .run(move || -> ApiResult<Vec<u8>> {
            let req = decode_segments(&headers, &body)?;
            let r = req.tool_radius.unwrap_or(meta.tool_radius_mm);
            let batch = SegmentBatch::concat(req.parts);
            // The exact route's per-segment check, so both take the same geometry.
            for (index, (cl, cc)) in batch.iter().enumerate() {
                geometry::check_segment(r, cl, cc).map_err(|e| geometry::Error::InSegment {
                    index,
                    source: Box::new(e),
                })?;
            }
            let p = predict_um(&reg, &meta.features, r, batch.iter())?;
            let warnings = outside_training(&p.inputs, reg.x_scaler());
            let e: Vec<f64> = p.um.into_iter().map(|v| v / 1000.0).collect();
            serde_json::to_vec(&PredictAnswer {
                step_errors: &e,
                tool_radius: r,
                unit: "mm",
                model: MODEL_KIND,
                warnings,
            })
            .map_err(ApiError::internal)
        })
        .await??;
    Ok(json_response(out))
}
