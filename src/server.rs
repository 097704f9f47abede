//! Starting and stopping the HTTP service: tokens, store, worker pool, router, listener.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use axum::Router;
use hyper::body::Incoming;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto::Builder;
use tokio::net::TcpListener;
use tokio::sync::{oneshot, watch};
use tokio::task::{JoinHandle, JoinSet};
use tower::ServiceExt as _;

use crate::api::{self, AppState, Tokens};
use crate::config::{Config, HEADER_TIMEOUT_RANGE_S};
use crate::jobs::JobPool;
use crate::store::Store;

/// A running service. Stop it with [`Server::stop`] (graceful: in-flight requests finish).
pub struct Server {
    addr: SocketAddr,
    state: AppState,
    shutdown: Option<oneshot::Sender<()>>,
    handle: JoinHandle<std::io::Result<()>>,
    grace: Duration,
}

/// Loads the tokens a configuration names and enforces the loopback rule:
/// without tokens only a loopback address may be bound.
pub fn load_tokens(config: &Config) -> Result<Tokens> {
    let tokens = match (&config.tokens_file, config.tokens_text()?) {
        (Some(path), Some(text)) => Tokens::parse(&text)
            .and_then(|t| {
                if t.is_empty() {
                    bail!("it holds no `TOKEN ROLE` entry");
                }
                Ok(t)
            })
            .with_context(|| format!("the tokens file {}", path.display()))?
            .with_read_limit(usize::from(config.read_token_concurrency)),
        (None, Some(spec)) => {
            Tokens::load(&spec)?.with_read_limit(usize::from(config.read_token_concurrency))
        }
        (_, None) => Tokens::default(),
    };
    if tokens.is_empty() && !config.addr.ip().is_loopback() {
        bail!(
            "refusing to listen on {}: no tokens are configured, and without tokens every \
             request is admin. Configure tokens (--tokens FILE, --tokens-file or TRUECUT_TOKENS, lines \
             `TOKEN ROLE` with ROLE read|write|admin) or bind a loopback address such as 127.0.0.1",
            config.addr
        );
    }
    Ok(tokens)
}

/// Opens the store, starts the worker pool (registering this instance and taking stored
/// jobs from the shared queue) and serves the API on `config.addr`
/// (port 0 picks a free port; see [`Server::addr`]).
pub async fn start(config: &Config) -> Result<Server> {
    let tokens = load_tokens(config)?;
    let body_timeout = std::time::Duration::try_from_secs_f64(config.body_timeout_s)
        .ok()
        .filter(|d| !d.is_zero())
        .ok_or_else(|| {
            anyhow::anyhow!(
                "--body-timeout-s must be a positive number of seconds, got {}",
                config.body_timeout_s
            )
        })?;
    let header_timeout = header_timeout(config.header_timeout_s)?;
    let limits = api::ranges::Limits::from_config(config)?;
    let inflight = (config.max_inflight_body_mb as u64).saturating_mul(1024 * 1024);
    if inflight < config.max_body_bytes as u64 {
        bail!(
            "--max-inflight-body-mb ({} MiB) is smaller than --max-body-bytes ({} bytes): the \
             largest accepted body could never be admitted; raise it or lower --max-body-bytes",
            config.max_inflight_body_mb,
            config.max_body_bytes
        );
    }
    crate::store::check_data_dir(&config.data_dir)?;
    let db_wait = Duration::try_from_secs_f64(config.db_wait_s).map_err(|_| {
        anyhow::anyhow!(
            "--db-wait-s must be a number of seconds >= 0, got {}",
            config.db_wait_s
        )
    })?;
    let database_url = config.database_url_with_password()?;
    let store = Store::open_waiting(&config.data_dir, database_url.as_deref(), db_wait).await?;
    let lease = Duration::try_from_secs_f64(config.lease_s)
        .ok()
        .filter(|d| *d >= Duration::from_millis(300))
        .ok_or_else(|| {
            anyhow::anyhow!(
                "--lease-s must be at least 0.3 seconds, got {}",
                config.lease_s
            )
        })?;
    let jobs = JobPool::start_with_lease(store.clone(), config.worker_count(), config.queue, lease)
        .await?;
    let state = AppState {
        store,
        jobs,
        tokens: Arc::new(tokens),
        metrics: Arc::new(api::metrics::Metrics::default()),
        max_body_bytes: config.max_body_bytes,
        pace: api::pace::Pace {
            stall: body_timeout,
            min_rate: config.min_body_rate,
            grace: api::pace::RATE_GRACE,
        },
        body_budget: Arc::new(api::admission::BodyBudget::new(
            inflight,
            config.max_body_bytes as u64,
            body_timeout,
        )),
        limits,
    };
    state
        .jobs
        .set_timeout(Some(config.job_timeout).filter(|t| !t.is_zero()));
    state
        .jobs
        .start_pruning(Some(config.job_retention).filter(|r| !r.is_zero()));
    state.jobs.serve(api::jobs::runners(&state));
    let app = api::router(state.clone());
    let listener = TcpListener::bind(config.addr)
        .await
        .with_context(|| format!("cannot listen on {}", config.addr))?;
    let addr = listener.local_addr()?;
    let (tx, rx) = oneshot::channel::<()>();
    let handle = tokio::spawn(serve(listener, app, header_timeout, async {
        let _ = rx.await;
    }));
    tracing::info!(%addr, backend = ?state.store.backend(), data_dir = %config.data_dir.display(), "truecut listening");
    Ok(Server {
        addr,
        state,
        shutdown: Some(tx),
        handle,
        grace: Duration::from_secs(config.shutdown_grace_s),
    })
}

/// `--header-timeout-s` as a duration; refused outside [`HEADER_TIMEOUT_RANGE_S`].
pub fn header_timeout(seconds: f64) -> Result<Duration> {
    if !HEADER_TIMEOUT_RANGE_S.contains(&seconds) {
        bail!(
            "--header-timeout-s must be between {} and {} seconds, got {seconds}: it is how long \
             a connection may take to send a request's headers before it is closed (default {})",
            HEADER_TIMEOUT_RANGE_S.start(),
            HEADER_TIMEOUT_RANGE_S.end(),
            crate::config::DEFAULT_HEADER_TIMEOUT_S
        );
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// Serves `app` on `listener` over HTTP/1 until `signal`, then stops accepting and waits for
/// the open connections to finish their requests (graceful shutdown, as `axum::serve`), with
/// hyper's header read timeout: a connection that has not sent a request's complete headers
/// within `header_timeout` (a slowloris client, or an idle kept-alive connection) is closed.
pub async fn serve(
    listener: TcpListener,
    app: Router,
    header_timeout: Duration,
    signal: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let (stop_tx, stop_rx) = watch::channel(false);
    let mut signal = std::pin::pin!(signal);
    let mut connections = JoinSet::new();
    loop {
        let stream = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, _peer)) => stream,
                Err(e) => {
                    // As axum::serve: out of descriptors or a connection reset before it was
                    // accepted must not end the server; wait a moment on the former.
                    if !is_connection_error(&e) {
                        tracing::error!("cannot accept a connection: {e}");
                        tokio::time::sleep(Duration::from_secs(1)).await;
                    }
                    continue;
                }
            },
            () = &mut signal => break,
        };
        let app = app.clone();
        let mut stop = stop_rx.clone();
        connections.spawn(async move {
            let service = hyper::service::service_fn(move |req: hyper::Request<Incoming>| {
                app.clone().oneshot(req.map(axum::body::Body::new))
            });
            let mut builder = Builder::new(TokioExecutor::new());
            builder
                .http1()
                .timer(TokioTimer::new())
                .header_read_timeout(header_timeout);
            let conn = builder.serve_connection_with_upgrades(TokioIo::new(stream), service);
            let mut conn = std::pin::pin!(conn);
            loop {
                tokio::select! {
                    result = conn.as_mut() => {
                        if let Err(e) = result {
                            tracing::trace!("connection ended: {e:#}");
                        }
                        break;
                    }
                    changed = stop.changed() => {
                        conn.as_mut().graceful_shutdown();
                        if changed.is_err() {
                            // The server is gone: nothing more to wait for but the connection.
                            let _ = conn.as_mut().await;
                            break;
                        }
                    }
                }
            }
        });
        // Reap the connections that ended, so the set holds only open ones.
        while connections.try_join_next().is_some() {}
    }
    drop(listener);
    let _ = stop_tx.send(true);
    while connections.join_next().await.is_some() {}
    Ok(())
}

/// Accept errors that concern one connection only (as hyper and axum treat them).
fn is_connection_error(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::ConnectionRefused
            | std::io::ErrorKind::ConnectionAborted
            | std::io::ErrorKind::ConnectionReset
    )
}

impl Server {
    /// The bound address.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The shared state (store, jobs) of the running service.
    pub fn state(&self) -> &AppState {
        &self.state
    }

    /// Graceful stop: stops accepting, lets in-flight requests finish, gives background
    /// jobs the grace period, records the rest as failed, closes the database.
    pub async fn stop(mut self) -> Result<()> {
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        // In-flight requests get the grace period; those still running after it are dropped
        // (their work stops at its next should-stop check, `numeric::stop`).
        let t0 = std::time::Instant::now();
        match tokio::time::timeout(self.grace, &mut self.handle).await {
            Ok(joined) => joined
                .context("server task failed")?
                .context("server error")?,
            Err(_) => {
                tracing::warn!(
                    grace_s = self.grace.as_secs_f64(),
                    "requests still running after the grace period were dropped"
                );
                self.handle.abort();
            }
        }
        let left = self.grace.saturating_sub(t0.elapsed());
        let cut = self.state.jobs.shutdown(left).await?;
        if cut > 0 {
            tracing::warn!(
                cut,
                "background jobs did not finish within the grace period; recorded as failed"
            );
        }
        self.state.jobs.release_runners();
        self.state.store.close().await;
        tracing::info!("truecut stopped");
        Ok(())
    }
}

impl Drop for Server {
    /// A server dropped without [`Server::stop`] (a test that ends) lets go of its stored-job
    /// runners, which hold its state: otherwise the state, and the database pool with its
    /// open connections, would outlive it.
    fn drop(&mut self) {
        self.state.jobs.release_runners();
    }
}
