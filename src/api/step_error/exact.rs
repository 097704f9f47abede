//! `POST /v1/step-error`: exact step errors of a segment batch, decoded while the body arrives
//! (`codec`) and solved on all cores (`step_error::solve_batch`), the answer written straight
//! into a buffer. Also the lean body checks the other step-error routes share.

use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use futures::StreamExt;

use crate::api::AppState;
use crate::api::error::{ApiError, ApiResult};
use crate::api::extract::is_json;
use crate::codec;
use crate::geometry::StepError;
use crate::step_error::{SegmentsBody, solve_batch};

pub(super) fn check_tool_radius(r: f64) -> ApiResult<()> {
    crate::api::ranges::check_tool_radius("tool_radius", r)
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

/// Decodes `{"tool_radius"?: mm, "segments": [...]}` (see [`codec`]: flat buffers, the large
/// bodies on all cores) and checks the radius and that there are segments.
pub fn decode_segments(headers: &HeaderMap, body: &[u8]) -> ApiResult<SegmentsBody> {
    require_json(headers)?;
    if body.is_empty() {
        return Err(empty_body());
    }
    let req = codec::decode(body, 0)?;
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
    let out_of_range = |p: &[[f64; 3]]| {
        p.iter()
            .flatten()
            .any(|c| c.is_finite() && c.abs() > crate::api::ranges::COORD_LIMIT_MM)
    };
    if let Some((i, (cl, cc))) = req
        .iter()
        .enumerate()
        .find(|(_, (cl, cc))| out_of_range(cl) || out_of_range(cc))
    {
        crate::api::ranges::check_coords(&format!("segments[{i}].cl"), &cl)?;
        crate::api::ranges::check_coords(&format!("segments[{i}].cc"), cc)?;
    }
    Ok(req)
}

fn empty_body() -> ApiError {
    ApiError::bad_request(
        "the request body is empty; send {\"tool_radius\": mm, \"segments\": [...]}",
    )
}

pub(super) fn json_response(body: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "application/json")], body).into_response()
}

/// Reads the body into blocks for [`codec::decode_blocks`] as it arrives (one copy of each
/// chunk), refusing more than `max` bytes; returns the number of bytes read.
async fn feed_body(
    body: Body,
    declared: Option<usize>,
    max: usize,
    tx: std::sync::mpsc::Sender<codec::Block>,
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
    let mut cutter = codec::BlockCutter::new(target, tx);
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

pub(super) async fn exact(
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
        let Some(req) = codec::decode_blocks(rx, threads)? else {
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
