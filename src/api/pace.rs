//! The pace of request bodies (issue 25): a body that stalls, or arrives slower than
//! `--min-body-rate`, is answered 408 and its connection freed, instead of a fixed total time.
//!
//! The rule, with `b` bytes received and `t` the time spent waiting for the client (the
//! clock runs only while the server waits for the next bytes, so a busy server does not
//! charge its own slowness to the client):
//! - a **stall**, no byte for `--body-timeout-s`, is 408;
//! - a body larger than [`SMALL_BODY_BYTES`] must keep `t ≤ GRACE + b / min_rate`, i.e. an
//!   average of at least `min_rate` after a grace of [`RATE_GRACE`];
//! - while at most [`SMALL_BODY_BYTES`] have arrived, the allowance is at least
//!   `--body-timeout-s` in total, so a small request works on a slow link.
//!
//! The verdict is kept beside the body: whatever the handler made of the failed read, the
//! answer becomes 408 with a sentence saying which limit was missed.

use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;

use axum::extract::{Request, State};
use axum::http::StatusCode;
use axum::middleware::Next;
use axum::response::Response;
use tokio::time::{Instant, Sleep};

use super::error::problem_response;

/// Time a body gets before the minimum rate applies.
pub const RATE_GRACE: Duration = Duration::from_secs(2);

/// Bodies up to this size are held to `--body-timeout-s` in total, never to the rate.
pub const SMALL_BODY_BYTES: u64 = 64 * 1024;

/// How fast a body must arrive.
#[derive(Clone, Copy, Debug)]
pub struct Pace {
    /// Longest pause between two pieces of a body (`--body-timeout-s`).
    pub stall: Duration,
    /// Slowest accepted average rate, bytes per second (`--min-body-rate`; 0: none).
    pub min_rate: u64,
    /// Time a body gets before the rate applies ([`RATE_GRACE`] in the service).
    pub grace: Duration,
}

impl Pace {
    /// Client time allowed for the first `bytes` of a body: `grace + bytes / min_rate`,
    /// at least `stall` while `bytes ≤ SMALL_BODY_BYTES`; unbounded without a minimum rate.
    pub fn allowance(&self, bytes: u64) -> Option<Duration> {
        if self.min_rate == 0 {
            return None;
        }
        let rated = self.grace + Duration::from_secs_f64(bytes as f64 / self.min_rate as f64);
        Some(if bytes <= SMALL_BODY_BYTES {
            rated.max(self.stall)
        } else {
            rated
        })
    }
}

/// Why a body was cut off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Missed {
    /// No byte for the stall time.
    Stall,
    /// Too slow on average.
    Rate {
        /// Bytes that had arrived.
        bytes: u64,
        /// Client time they took.
        waited: Duration,
    },
}

/// The sentence of the 408 answer.
pub fn sentence(pace: &Pace, missed: Missed) -> String {
    match missed {
        Missed::Stall => format!(
            "the request body stopped arriving: no byte for {} s (--body-timeout-s); send it \
             without pauses",
            pace.stall.as_secs_f64()
        ),
        Missed::Rate { bytes, waited } => format!(
            "the request body arrived too slowly: {bytes} bytes in {:.1} s, {:.1} KiB/s, below \
             this server's minimum of {:.1} KiB/s after {} s (--min-body-rate); send it over a \
             faster link or split the upload",
            waited.as_secs_f64(),
            bytes as f64 / 1024.0 / waited.as_secs_f64().max(1e-3),
            pace.min_rate as f64 / 1024.0,
            pace.grace.as_secs_f64()
        ),
    }
}

/// Middleware: paces the request's body (module docs); a body cut off answers 408.
pub async fn paced_body(State(pace): State<Pace>, req: Request, next: Next) -> Response {
    let verdict = Arc::new(Mutex::new(None));
    let (parts, body) = req.into_parts();
    let body = axum::body::Body::new(PacedBody {
        inner: body,
        pace,
        bytes: 0,
        waited: Duration::ZERO,
        since: None,
        timer: Box::pin(tokio::time::sleep(Duration::ZERO)),
        verdict: verdict.clone(),
    });
    let resp = next.run(Request::from_parts(parts, body)).await;
    let missed = *verdict.lock().expect("body verdict");
    match missed {
        Some(missed) => problem_response(StatusCode::REQUEST_TIMEOUT, &sentence(&pace, missed)),
        None => resp,
    }
}

/// A request body that fails with [`BodyTooSlow`] once it misses its [`Pace`].
struct PacedBody {
    inner: axum::body::Body,
    pace: Pace,
    /// Bytes received so far.
    bytes: u64,
    /// Client time spent before the current wait.
    waited: Duration,
    /// When the current wait for bytes began (`None`: not waiting).
    since: Option<Instant>,
    /// Fires at the current wait's deadline.
    timer: Pin<Box<Sleep>>,
    verdict: Arc<Mutex<Option<Missed>>>,
}

/// The error a [`PacedBody`] read ends with.
#[derive(Debug, thiserror::Error)]
#[error("the request body did not arrive in time")]
struct BodyTooSlow;

impl PacedBody {
    /// Starts a wait at `now`: the timer is set to the earlier of the stall and the rate
    /// deadline.
    fn start_wait(&mut self, now: Instant) {
        self.since = Some(now);
        let mut until = self.pace.stall;
        if let Some(allowed) = self.pace.allowance(self.bytes) {
            until = until.min(allowed.saturating_sub(self.waited));
        }
        self.timer.as_mut().reset(now + until);
    }

    /// Which limit the wait that began at `since` missed.
    fn missed(&self, since: Instant, now: Instant) -> Missed {
        let waited = self.waited + (now - since);
        match self.pace.allowance(self.bytes) {
            Some(allowed) if waited >= allowed && now - since < self.pace.stall => Missed::Rate {
                bytes: self.bytes,
                waited,
            },
            _ => Missed::Stall,
        }
    }
}

impl http_body::Body for PacedBody {
    type Data = bytes::Bytes;
    type Error = axum::BoxError;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>> {
        if let Poll::Ready(frame) = Pin::new(&mut self.inner).poll_frame(cx) {
            if let Some(since) = self.since.take() {
                let now = Instant::now();
                self.waited += now - since;
            }
            if let Some(Ok(f)) = &frame
                && let Some(data) = f.data_ref()
            {
                self.bytes += data.len() as u64;
            }
            return Poll::Ready(frame.map(|f| f.map_err(Into::into)));
        }
        let since = match self.since {
            Some(since) => since,
            None => {
                let now = Instant::now();
                self.start_wait(now);
                now
            }
        };
        if self.timer.as_mut().poll(cx).is_ready() {
            let missed = self.missed(since, Instant::now());
            *self.verdict.lock().expect("body verdict") = Some(missed);
            return Poll::Ready(Some(Err(BodyTooSlow.into())));
        }
        Poll::Pending
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

#[cfg(test)]
mod tests;
