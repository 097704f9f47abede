//! `truecut serve`: run the service until SIGINT or SIGTERM, then stop gracefully.

use crate::config::Config;

/// Starts the service (and loads the demo data with `--demo`), waits for a signal,
/// stops gracefully. Exit status 0 after a signal.
pub fn run(config: Config) -> anyhow::Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async move {
        let server = crate::server::start(&config).await?;
        if config.demo {
            let loaded = super::demo::load(&server.state().store).await?;
            if loaded {
                tracing::info!(
                    "demo loaded: machine 'demo', surface 'saddle', measurement 'demo-1'"
                );
            }
        }
        eprintln!(
            "truecut listening on http://{} (try: curl http://{}/healthz)",
            server.addr(),
            server.addr()
        );
        shutdown_signal().await;
        tracing::info!("signal received, shutting down");
        server.stop().await
    })
}

/// Resolves on SIGINT (Ctrl-C) or SIGTERM.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = term => {},
    }
}
