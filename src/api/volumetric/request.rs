//! Request side of the volumetric-map resource: the PUT options (JSON body or, for CSV
//! uploads, the query string), the predict body, the table's query, the limits a request
//! must respect, and their translation into the core's [`FitOptions`].

use std::collections::HashMap;

use serde::Deserialize;

use crate::api::error::{ApiError, ApiResult};
use crate::volumetric::{AxisLines, FitOptions, ModelKind, NetworkOptions, ResidualKind};

/// Most nodes fitted synchronously (openapi.yaml: sync up to 20,000 nodes).
pub const MAX_NODES: usize = 20_000;
/// Most points predicted in one request (openapi.yaml: sync up to 100,000 points).
pub const MAX_POINTS: usize = 100_000;
/// Most training epochs a client may ask for.
pub const MAX_EPOCHS: usize = 20_000;
/// Most epochs × nodes a client may ask for per network (auto trains up to 17 networks
/// in its cross-validation; this keeps a request under about a minute).
pub const MAX_SAMPLE_PASSES: usize = 4_000_000;

/// Options that may come in the JSON body or, for CSV uploads, the query string.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MapRequest {
    pub(super) nodes: Option<Vec<[f64; 3]>>,
    pub(super) errors: Option<Vec<[f64; 3]>>,
    pub(super) lines: Option<AxisLines>,
    pub(super) model: Option<String>,
    pub(super) tool_offset_mm: Option<[f64; 3]>,
    pub(super) degree: Option<usize>,
    pub(super) residual: Option<String>,
    pub(super) max_points_per_axis: Option<usize>,
    pub(super) hidden: Option<usize>,
    pub(super) epochs: Option<usize>,
    pub(super) seed: Option<u64>,
    pub(super) sigmoid_output: Option<bool>,
}

pub(super) fn parse_triple(field: &str, v: &str) -> ApiResult<[f64; 3]> {
    let parts: Vec<Option<f64>> = v
        .split(',')
        .map(|s| s.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect();
    match parts.as_slice() {
        [Some(a), Some(b), Some(c)] => Ok([*a, *b, *c]),
        _ => Err(ApiError::bad_request(format!(
            "{field} must be three finite numbers separated by commas, e.g. {field}=0,0,-150 (got '{v}')"
        ))),
    }
}

pub(super) fn parse_query<T: std::str::FromStr>(
    q: &HashMap<String, String>,
    field: &str,
) -> ApiResult<Option<T>> {
    q.get(field)
        .map(|v| {
            v.parse::<T>().map_err(|_| {
                ApiError::bad_request(format!(
                    "query parameter {field}='{v}' is not a valid value"
                ))
            })
        })
        .transpose()
}

pub(super) fn options_from_query(q: &HashMap<String, String>) -> ApiResult<MapRequest> {
    const KNOWN: [&str; 9] = [
        "model",
        "tool_offset_mm",
        "degree",
        "residual",
        "max_points_per_axis",
        "hidden",
        "epochs",
        "seed",
        "sigmoid_output",
    ];
    if let Some(k) = q.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        return Err(ApiError::bad_request(format!(
            "unknown query parameter '{k}': use {}",
            KNOWN.join(", ")
        )));
    }
    Ok(MapRequest {
        model: q.get("model").cloned(),
        tool_offset_mm: q
            .get("tool_offset_mm")
            .map(|v| parse_triple("tool_offset_mm", v))
            .transpose()?,
        degree: parse_query(q, "degree")?,
        residual: q.get("residual").cloned(),
        max_points_per_axis: parse_query(q, "max_points_per_axis")?,
        hidden: parse_query(q, "hidden")?,
        epochs: parse_query(q, "epochs")?,
        seed: parse_query(q, "seed")?,
        sigmoid_output: parse_query(q, "sigmoid_output")?,
        ..MapRequest::default()
    })
}

pub(super) fn fit_options(r: &MapRequest) -> ApiResult<FitOptions> {
    let d = FitOptions::default();
    let model = match &r.model {
        Some(m) => ModelKind::parse(m)?,
        None => ModelKind::Auto,
    };
    if let Some(e) = r.epochs
        && !(1..=MAX_EPOCHS).contains(&e)
    {
        return Err(ApiError::bad_request(format!(
            "epochs must be between 1 and {MAX_EPOCHS} (default: about 40,000 mini-batch steps), got {e}"
        )));
    }
    let residual = match r.residual.as_deref() {
        None => d.residual,
        Some(s) => ResidualKind::parse(s).ok_or_else(|| {
            ApiError::bad_request(format!(
                "residual must be \"spline\" or \"network\" (what the hybrid fits to the kinematic model's residual), got '{s}'"
            ))
        })?,
    };
    Ok(FitOptions {
        model,
        tool_offset_mm: r.tool_offset_mm.unwrap_or(d.tool_offset_mm),
        degree: r.degree.unwrap_or(d.degree),
        residual,
        max_points_per_axis: r.max_points_per_axis,
        network: NetworkOptions {
            hidden: r.hidden.unwrap_or(d.network.hidden),
            sigmoid_output: r.sigmoid_output.unwrap_or(d.network.sigmoid_output),
            epochs: r.epochs,
            seed: r.seed.unwrap_or(d.network.seed),
        },
        ..d
    })
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PredictRequest {
    pub(super) points: Vec<[f64; 3]>,
}

pub(super) fn parse_counts(v: &str) -> ApiResult<[usize; 3]> {
    let parts: Vec<Option<usize>> = v.split(',').map(|s| s.trim().parse().ok()).collect();
    match parts.as_slice() {
        [Some(n)] => Ok([*n; 3]),
        [Some(a), Some(b), Some(c)] => Ok([*a, *b, *c]),
        _ => Err(ApiError::bad_request(format!(
            "points must be one count or three counts separated by commas, e.g. points=11,9,7 (got '{v}')"
        ))),
    }
}
