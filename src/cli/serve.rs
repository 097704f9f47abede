//! `truecut serve`: run the service until SIGINT or SIGTERM, then stop gracefully.

use crate::config::Config;

/// Starts the service (and loads the demo data with `--demo`), waits for a signal,
/// stops gracefully. Exit status 0 after a signal.
pub fn run(config: Config) -> anyhow::Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let result = runtime.block_on(async move {
        let server = crate::server::start(&config).await?;
        if config.demo {
            let loaded = super::demo::load(&server.state().store).await?;
            if loaded {
                tracing::info!(
                    "demo loaded: machine 'demo', surface 'saddle', measurements 'demo-1' and 'demo-2', machine 'demo-vmc' with a volumetric map; dashboard at /"
                );
            }
        }
        // Install the handlers before announcing the address, so a signal sent right after
        // the announcement is never handled by the default action (kill).
        let signal = shutdown_signal()?;
        eprintln!(
            "truecut listening on http://{} (try: curl http://{}/healthz)",
            server.addr(),
            server.addr()
        );
        signal.await;
        tracing::info!("signal received, shutting down");
        server.stop().await
    });
    // Work that ignored its stop request must not hold the process past the grace.
    runtime.shutdown_timeout(std::time::Duration::from_secs(1));
    result
}

/// Installs SIGINT and SIGTERM handlers now; the returned future resolves on either.
#[cfg(unix)]
pub fn shutdown_signal() -> anyhow::Result<impl std::future::Future<Output = ()>> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut int = signal(SignalKind::interrupt())?;
    let mut term = signal(SignalKind::terminate())?;
    Ok(async move {
        tokio::select! {
            _ = int.recv() => {},
            _ = term.recv() => {},
        }
    })
}

/// Installs the Ctrl-C handler; the returned future resolves on Ctrl-C.
#[cfg(not(unix))]
pub fn shutdown_signal() -> anyhow::Result<impl std::future::Future<Output = ()>> {
    Ok(async {
        let _ = tokio::signal::ctrl_c().await;
    })
}
