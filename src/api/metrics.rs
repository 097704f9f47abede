//! `GET /metrics`: Prometheus text exposition (requests by route and status, latency
//! histogram by route, answers to database outages, job gauges, job outcomes and run times
//! by kind, jobs taken back by reason, the lease). Hand-written: a few counters do not need
//! a crate. Every label is bounded: route templates, standard methods, statuses, the code's
//! job kinds and fixed outcome and reason names.

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
    outage_answers: u64,
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

    /// Counts an answer to a database outage (503 + Retry-After, [`super::error::OutageAnswer`]).
    pub fn record_outage_answer(&self) {
        self.inner
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .outage_answers += 1;
    }

    /// The Prometheus text exposition of everything recorded, plus the pool's gauges,
    /// counters and lease.
    pub fn render(&self, jobs: &crate::jobs::JobPool) -> String {
        let (queued, running, rejected) = (jobs.queued(), jobs.running(), jobs.rejected());
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
        out.push_str("# HELP truecut_database_outage_answers_total Requests answered 503 + Retry-After because the database was out (cut connection, failover, no free connection).\n# TYPE truecut_database_outage_answers_total counter\n");
        let _ = writeln!(
            out,
            "truecut_database_outage_answers_total {}",
            inner.outage_answers
        );
        drop(inner);
        render_jobs(&mut out, &jobs.stats(), &jobs.lease_report());
        out
    }
}

/// Job outcomes and run times by kind, jobs taken back by reason, and the lease.
fn render_jobs(
    out: &mut String,
    stats: &crate::jobs::StatsSnapshot,
    lease: &crate::store::LeaseReport,
) {
    out.push_str("# HELP truecut_jobs_finished_total Job runs on this instance by kind and outcome (done, failed, timed_out, cancelled: while queued, requeued: database outage, not_stored: cancelled or taken back while running).\n# TYPE truecut_jobs_finished_total counter\n");
    for (kind, outcome, n) in &stats.outcomes {
        let _ = writeln!(
            out,
            "truecut_jobs_finished_total{{kind=\"{}\",outcome=\"{outcome}\"}} {n}",
            escape(kind)
        );
    }
    out.push_str("# HELP truecut_job_run_seconds Time a job's work ran on a worker, by kind.\n# TYPE truecut_job_run_seconds histogram\n");
    for (kind, h) in &stats.run_times {
        let k = escape(kind);
        for (i, le) in crate::jobs::RUN_BUCKETS_S.iter().enumerate() {
            let _ = writeln!(
                out,
                "truecut_job_run_seconds_bucket{{kind=\"{k}\",le=\"{le}\"}} {}",
                h.counts[i]
            );
        }
        let _ = writeln!(
            out,
            "truecut_job_run_seconds_bucket{{kind=\"{k}\",le=\"+Inf\"}} {}",
            h.count
        );
        let _ = writeln!(
            out,
            "truecut_job_run_seconds_sum{{kind=\"{k}\"}} {}",
            h.sum_s
        );
        let _ = writeln!(
            out,
            "truecut_job_run_seconds_count{{kind=\"{k}\"}} {}",
            h.count
        );
    }
    out.push_str("# HELP truecut_jobs_requeued_total Jobs this instance put back in the queue, by reason (dead_instance: another's lease expired, shutdown, lost_claim, orphan).\n# TYPE truecut_jobs_requeued_total counter\n");
    for (why, n) in &stats.requeued {
        let _ = writeln!(out, "truecut_jobs_requeued_total{{reason=\"{why}\"}} {n}");
    }
    out.push_str("# HELP truecut_jobs_taken_back_failed_total Jobs this instance failed when taking them back (no stored input, or out of attempts), by reason.\n# TYPE truecut_jobs_taken_back_failed_total counter\n");
    for (why, n) in &stats.failed {
        let _ = writeln!(
            out,
            "truecut_jobs_taken_back_failed_total{{reason=\"{why}\"}} {n}"
        );
    }
    out.push_str("# HELP truecut_lease_held 1 while this instance's lease is held (renewed within it), else 0.\n# TYPE truecut_lease_held gauge\n");
    let _ = writeln!(out, "truecut_lease_held {}", u8::from(lease.held));
    out.push_str("# HELP truecut_lease_fenced 1 while this instance is fenced (its lease lapsed: it claims and commits nothing until it registers again).\n# TYPE truecut_lease_fenced gauge\n");
    let _ = writeln!(out, "truecut_lease_fenced {}", u8::from(lease.fenced));
    out.push_str("# HELP truecut_lease_renewal_failures Lease renewals failed in a row.\n# TYPE truecut_lease_renewal_failures gauge\n");
    let _ = writeln!(
        out,
        "truecut_lease_renewal_failures {}",
        lease.failures_in_a_row
    );
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
    let body = state.metrics.render(&state.jobs);
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
    if resp
        .extensions()
        .get::<super::error::OutageAnswer>()
        .is_some()
    {
        state.metrics.record_outage_answer();
    }
    state.metrics.record(
        &route,
        method,
        resp.status().as_u16(),
        start.elapsed().as_secs_f64(),
    );
    resp
}
