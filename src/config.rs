//! Service configuration: command-line flags and environment variables, one struct.

use std::net::SocketAddr;
use std::path::PathBuf;

/// Default request body limit: 128 MiB. A 250,000-point JSON upload is about 15 MiB and a
/// 100,000-segment step-error body with 5-point contact curves about 60 MiB; the limit leaves
/// room for longer contact curves while bounding memory per request.
pub const DEFAULT_MAX_BODY_BYTES: usize = 128 * 1024 * 1024;

/// Everything `truecut serve` needs. Parsed by clap (`truecut serve --help`), also built
/// directly by tests and benches.
#[derive(Clone, Debug, clap::Args)]
pub struct Config {
    /// Address to listen on (HOST:PORT). A non-loopback address requires tokens.
    #[arg(long, default_value = "127.0.0.1:8080", env = "TRUECUT_ADDR")]
    pub addr: SocketAddr,

    /// Directory for the embedded SQLite database and the model files.
    #[arg(long, default_value = "./truecut-data", env = "TRUECUT_DATA_DIR")]
    pub data_dir: PathBuf,

    /// Database URL: `sqlite://FILE` or `postgres://...`. Default: SQLite file `truecut.db`
    /// in the data dir.
    #[arg(long, env = "DATABASE_URL")]
    pub database_url: Option<String>,

    /// Tokens: a file with lines `TOKEN ROLE` (role read, write or admin), or the same
    /// entries inline separated by commas or newlines (e.g. `s3cret admin,r3ad read`).
    /// Without tokens the service binds loopback only and treats every request as admin.
    #[arg(long, env = "TRUECUT_TOKENS")]
    pub tokens: Option<String>,

    /// Load a demo machine `demo` with surface `saddle` and a probe measurement `demo-1`
    /// (only if machine `demo` does not exist yet).
    #[arg(long)]
    pub demo: bool,

    /// Worker threads for CPU-heavy work (default: number of CPUs).
    #[arg(long, env = "TRUECUT_WORKERS")]
    pub workers: Option<usize>,

    /// Requests and jobs that may wait for a worker before new ones get 503 + Retry-After.
    #[arg(long, default_value_t = 32, env = "TRUECUT_QUEUE")]
    pub queue: usize,

    /// Largest accepted request body in bytes (larger bodies get 413).
    #[arg(long, default_value_t = DEFAULT_MAX_BODY_BYTES, env = "TRUECUT_MAX_BODY_BYTES")]
    pub max_body_bytes: usize,

    /// Seconds a request body may take to arrive after its headers (or stall) before the
    /// request is answered 408 and its connection freed.
    #[arg(long, default_value_t = 30.0, env = "TRUECUT_BODY_TIMEOUT_S")]
    pub body_timeout_s: f64,

    /// Seconds that in-flight background jobs get to finish at shutdown before they are
    /// recorded as failed.
    #[arg(long, default_value_t = 30, env = "TRUECUT_SHUTDOWN_GRACE_S")]
    pub shutdown_grace_s: u64,

    /// Seconds of this instance's lease: it renews it every third of that, and when it
    /// stops renewing (crash, kill, lost network) the other instances on the database
    /// re-queue or fail its jobs once it has expired. Shorter: faster fail-over; too short
    /// for the database's latency: live instances judged gone.
    #[arg(long, default_value_t = 10.0, env = "TRUECUT_LEASE_S")]
    pub lease_s: f64,
}

impl Config {
    /// A configuration with every default, serving `addr` from `data_dir` (tests, benches).
    pub fn new(addr: SocketAddr, data_dir: PathBuf) -> Self {
        Config {
            addr,
            data_dir,
            database_url: None,
            tokens: None,
            demo: false,
            workers: None,
            queue: 32,
            max_body_bytes: DEFAULT_MAX_BODY_BYTES,
            body_timeout_s: 30.0,
            shutdown_grace_s: 30,
            lease_s: 10.0,
        }
    }

    /// Number of worker threads to use.
    pub fn worker_count(&self) -> usize {
        self.workers
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()))
            .max(1)
    }
}
