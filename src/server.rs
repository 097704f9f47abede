//! Starting and stopping the HTTP service: tokens, store, worker pool, router, listener.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

use crate::api::{self, AppState, Tokens};
use crate::config::Config;
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
    let tokens = match &config.tokens {
        Some(spec) => Tokens::load(spec)?,
        None => Tokens::default(),
    };
    if tokens.is_empty() && !config.addr.ip().is_loopback() {
        bail!(
            "refusing to listen on {}: no tokens are configured, and without tokens every \
             request is admin. Configure tokens (--tokens FILE or TRUECUT_TOKENS, lines \
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
    let store =
        Store::open_waiting(&config.data_dir, config.database_url.as_deref(), db_wait).await?;
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
    let listener = tokio::net::TcpListener::bind(config.addr)
        .await
        .with_context(|| format!("cannot listen on {}", config.addr))?;
    let addr = listener.local_addr()?;
    let (tx, rx) = oneshot::channel::<()>();
    let handle = tokio::spawn(async move {
        axum::serve(listener, app)
            .with_graceful_shutdown(async {
                let _ = rx.await;
            })
            .await
    });
    tracing::info!(%addr, backend = ?state.store.backend(), data_dir = %config.data_dir.display(), "truecut listening");
    Ok(Server {
        addr,
        state,
        shutdown: Some(tx),
        handle,
        grace: Duration::from_secs(config.shutdown_grace_s),
    })
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
        (&mut self.handle)
            .await
            .context("server task failed")?
            .context("server error")?;
        let cut = self.state.jobs.shutdown(self.grace).await?;
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
