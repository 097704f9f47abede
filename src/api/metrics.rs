//! `GET /metrics`: Prometheus text exposition (requests by route and status, latency
//! histogram by route, job gauges). Hand-written: a few counters do not need a crate.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::time::Instant;

use axum::Router;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::get;

use super::AppState;

/// Upper bounds (seconds) of the latency histogram buckets.
const BUCKETS_S: [f64; 12] = [
    0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 10.0,
];

#[derive(Default)]
struct Histogram {
    counts: [u64; BUCKETS_S.len()],
    sum_s: f64,
    count: u64,
}

#[derive(Default)]
struct Inner {
    requests: BTreeMap<(String, String, u16), u64>,
    latency: BTreeMap<String, Histogram>,
}

/// Request counters and latency histograms.
#[derive(Default)]
pub struct Metrics {
    inner: Mutex<Inner>,
}

impl Metrics {
    /// Records one request: route template, method, status and duration in seconds.
    pub fn record(&self, route: &str, method: &str, status: u16, seconds: f64) {
        let mut inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        *inner
            .requests
            .entry((route.to_string(), method.to_string(), status))
            .or_default() += 1;
        let h = inner.latency.entry(route.to_string()).or_default();
        for (i, le) in BUCKETS_S.iter().enumerate() {
            if seconds <= *le {
                h.counts[i] += 1;
            }
        }
        h.sum_s += seconds;
        h.count += 1;
    }

    /// The Prometheus text exposition of everything recorded, plus the job gauges.
    pub fn render(&self, queued: usize, running: usize, rejected: u64) -> String {
        let inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        let mut out = String::new();
        out.push_str("# HELP truecut_http_requests_total HTTP requests by route template, method and status.\n");
        out.push_str("# TYPE truecut_http_requests_total counter\n");
        for ((route, method, status), n) in &inner.requests {
            let _ = writeln!(
                out,
                "truecut_http_requests_total{{route=\"{}\",method=\"{}\",status=\"{status}\"}} {n}",
                escape(route),
                escape(method)
            );
        }
        out.push_str("# HELP truecut_http_request_duration_seconds Time to the response head, by route template.\n");
        out.push_str("# TYPE truecut_http_request_duration_seconds histogram\n");
        for (route, h) in &inner.latency {
            let r = escape(route);
            for (i, le) in BUCKETS_S.iter().enumerate() {
                let _ = writeln!(
                    out,
                    "truecut_http_request_duration_seconds_bucket{{route=\"{r}\",le=\"{le}\"}} {}",
                    h.counts[i]
                );
            }
            let _ = writeln!(
                out,
                "truecut_http_request_duration_seconds_bucket{{route=\"{r}\",le=\"+Inf\"}} {}",
                h.count
            );
            let _ = writeln!(
                out,
                "truecut_http_request_duration_seconds_sum{{route=\"{r}\"}} {}",
                h.sum_s
            );
            let _ = writeln!(
                out,
                "truecut_http_request_duration_seconds_count{{route=\"{r}\"}} {}",
                h.count
            );
        }
        out.push_str("# HELP truecut_jobs_queued Work items waiting for a worker.\n# TYPE truecut_jobs_queued gauge\n");
        let _ = writeln!(out, "truecut_jobs_queued {queued}");
        out.push_str("# HELP truecut_jobs_running Work items running now.\n# TYPE truecut_jobs_running gauge\n");
        let _ = writeln!(out, "truecut_jobs_running {running}");
        out.push_str("# HELP truecut_jobs_rejected_total Work turned away with 503 because the pool was full.\n# TYPE truecut_jobs_rejected_total counter\n");
        let _ = writeln!(out, "truecut_jobs_rejected_total {rejected}");
        out
    }
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new().route("/metrics", get(metrics))
}

async fn metrics(State(state): State<AppState>) -> Response {
    let body = state.metrics.render(
        state.jobs.queued(),
        state.jobs.running(),
        state.jobs.rejected(),
    );
    (
        [(
            header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        body,
    )
        .into_response()
}

/// The `method` label of a request: the standard methods by name, any other `other`, so a
/// client sending made-up methods cannot grow the series without bound.
pub fn method_label(method: &Method) -> &'static str {
    match *method {
        Method::GET => "GET",
        Method::HEAD => "HEAD",
        Method::POST => "POST",
        Method::PUT => "PUT",
        Method::PATCH => "PATCH",
        Method::DELETE => "DELETE",
        Method::OPTIONS => "OPTIONS",
        _ => "other",
    }
}

/// Middleware: counts each request by route template (`unmatched` for unknown paths) and
/// method ([`method_label`]: standard methods, else `other`).
pub async fn track(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    let method = method_label(req.method());
    let start = Instant::now();
    let resp = next.run(req).await;
    state.metrics.record(
        &route,
        method,
        resp.status().as_u16(),
        start.elapsed().as_secs_f64(),
    );
    resp
}
