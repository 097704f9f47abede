//! Service configuration: command-line flags and environment variables, one struct.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

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

    /// Database password, for a `postgres://USER@HOST/DB` URL that holds none: a file whose
    /// text (a trailing newline dropped) is the password, read once at start and put into
    /// the URL, so the secret is neither in the environment nor on the command line
    /// (compose.yaml's generated secrets, an orchestrator's secret files).
    #[arg(long, env = "TRUECUT_DATABASE_PASSWORD_FILE")]
    pub database_password_file: Option<PathBuf>,

    /// Tokens: a file with lines `TOKEN ROLE` (role read, write or admin), or the same
    /// entries inline separated by commas or newlines (e.g. `s3cret admin,r3ad read`).
    /// Without tokens the service binds loopback only and treats every request as admin.
    #[arg(long, env = "TRUECUT_TOKENS")]
    pub tokens: Option<String>,

    /// Tokens from a file only (lines `TOKEN ROLE`), read once at start: unlike --tokens, a
    /// missing or unreadable file stops the start with a sentence instead of being read as
    /// inline entries. Not together with --tokens.
    #[arg(long, env = "TRUECUT_TOKENS_FILE", conflicts_with = "tokens")]
    pub tokens_file: Option<PathBuf>,

    /// POST requests (computations) each read token may have in flight at once; more answer
    /// 429 with Retry-After. Write and admin tokens are bounded by the worker pool only.
    #[arg(long, default_value_t = 1, env = "TRUECUT_READ_TOKEN_CONCURRENCY",
          value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub read_token_concurrency: u16,

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

    /// Seconds a request body may pause (no byte arriving) before the request is answered
    /// 408 and its connection freed; also the whole time a small body (at most 64 KiB) may
    /// take, so small requests work on slow links.
    #[arg(long, default_value_t = 30.0, env = "TRUECUT_BODY_TIMEOUT_S")]
    pub body_timeout_s: f64,

    /// Seconds a connection may take to send a request's headers (the first request's, and
    /// the next one's on a kept-alive connection) before it is closed without an answer: a
    /// client that opens connections and never finishes their headers (slowloris) holds
    /// each for at most this long. Between 0.5 and 600.
    #[arg(long, default_value_t = DEFAULT_HEADER_TIMEOUT_S, env = "TRUECUT_HEADER_TIMEOUT_S")]
    pub header_timeout_s: f64,

    /// Slowest average rate at which a body larger than 64 KiB may arrive, after a grace of
    /// 2 s: bytes per second, or a number with a unit `KiB`, `MiB` (per second), e.g. `64KiB`.
    /// A slower body is answered 408. `0`: no minimum (only --body-timeout-s applies).
    #[arg(long, default_value = "64KiB", value_parser = parse_rate, env = "TRUECUT_MIN_BODY_RATE")]
    pub min_body_rate: u64,

    /// Seconds that in-flight requests and background jobs get to finish at shutdown: then
    /// requests still running are dropped, and jobs go back to the queue (or are recorded as
    /// failed); the process ends a second later whatever is still computing.
    #[arg(long, default_value_t = 30, env = "TRUECUT_SHUTDOWN_GRACE_S")]
    pub shutdown_grace_s: u64,

    /// Seconds of this instance's lease: it renews it every third of that, and when it
    /// stops renewing (crash, kill, lost network) the other instances on the database
    /// re-queue or fail its jobs once it has expired. Shorter: faster fail-over; too short
    /// for the database's latency: live instances judged gone.
    #[arg(long, default_value_t = 10.0, env = "TRUECUT_LEASE_S")]
    pub lease_s: f64,

    /// Seconds to wait at start for a database that does not answer yet (refused or
    /// unresolved connections are retried every second): an instance started beside its
    /// database, as in compose.yaml, waits instead of exiting. 0: fail at once.
    #[arg(long, default_value_t = 0.0, env = "TRUECUT_DB_WAIT_S")]
    pub db_wait_s: f64,

    /// MiB of request bodies the whole process holds at once (declared Content-Length; a
    /// chunked body counts as --max-body-bytes). Requests beyond it wait up to
    /// --body-timeout-s for room, then get 503 + Retry-After. Bounds the memory of
    /// concurrent large uploads (BENCHMARKS.md, "Concurrent uploads").
    #[arg(long, default_value_t = DEFAULT_MAX_INFLIGHT_BODY_MB, env = "TRUECUT_MAX_INFLIGHT_BODY_MB")]
    pub max_inflight_body_mb: usize,

    /// How long ended jobs (done, failed, cancelled) and their results are kept before they
    /// are deleted: a number of seconds or a number with a unit `s`, `m`, `h` or `d` (e.g.
    /// `7d`, `12h`). `0` keeps them for ever. A job's input is dropped as soon as it ends.
    #[arg(long, default_value = "7d", value_parser = parse_duration, env = "TRUECUT_JOB_RETENTION")]
    pub job_retention: Duration,

    /// Longest a job, or a request's computation, may run before it is stopped (the job ends
    /// `failed` saying so, the request gets 503): seconds or a number with a unit `s`, `m`,
    /// `h` or `d`. `0`: no limit.
    #[arg(long, default_value = "6h", value_parser = parse_duration, env = "TRUECUT_JOB_TIMEOUT")]
    pub job_timeout: Duration,

    /// Plausibility limit of a probe deviation, mm: a measurement whose deviation from the
    /// nominal (along the normal) exceeds it in magnitude is refused (400 naming the point).
    #[arg(long, default_value_t = DEFAULT_MAX_DEVIATION_MM, env = "TRUECUT_MAX_DEVIATION_MM")]
    pub max_deviation_mm: f64,

    /// Largest tangential distance, mm, of a measured point from the nominal it is paired
    /// with (points are paired by order); also never more than half the local grid
    /// spacing. Beyond it the upload is refused as reversed or shifted.
    #[arg(long, default_value_t = DEFAULT_MAX_TANGENTIAL_MM, env = "TRUECUT_MAX_TANGENTIAL_MM")]
    pub max_tangential_mm: f64,
}

/// Default `--header-timeout-s`: 10 s.
pub const DEFAULT_HEADER_TIMEOUT_S: f64 = 10.0;

/// The accepted range of `--header-timeout-s`, seconds.
pub const HEADER_TIMEOUT_RANGE_S: std::ops::RangeInclusive<f64> = 0.5..=600.0;

/// Default `--job-retention`: 7 days.
pub const DEFAULT_JOB_RETENTION: Duration = Duration::from_secs(7 * 24 * 3600);

/// Default `--job-timeout`: 6 hours (training on the largest accepted batch takes minutes;
/// the limit is for work that runs away, not for big work).
pub const DEFAULT_JOB_TIMEOUT: Duration = Duration::from_secs(6 * 3600);

/// Reads a duration flag: a whole or decimal number of seconds, or a number followed by
/// `s`, `m`, `h` or `d` (`90s`, `15m`, `12h`, `7d`).
pub fn parse_duration(s: &str) -> Result<Duration, String> {
    let t = s.trim();
    let (number, unit) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => (&t[..i], c),
        _ => (t, 's'),
    };
    let scale = match unit {
        's' => 1.0,
        'm' => 60.0,
        'h' => 3600.0,
        'd' => 86_400.0,
        _ => {
            return Err(format!(
                "'{s}': the unit must be s, m, h or d (e.g. 7d, 12h, 90s)"
            ));
        }
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a duration: write e.g. 7d, 12h, 15m, 90s or 30"))?;
    Duration::try_from_secs_f64(value * scale)
        .map_err(|_| format!("'{s}' must be a finite duration of 0 or more"))
}

/// Default `--min-body-rate`: 64 KiB/s, bytes per second. A 128 MiB body at that rate takes
/// 34 minutes; a shop-floor link is hundreds of times faster, a slowloris client is not.
pub const DEFAULT_MIN_BODY_RATE: u64 = 64 * 1024;

/// Reads a rate flag in bytes per second: a whole number of bytes, or a number followed by
/// `K`/`KiB`/`KB` (×1024) or `M`/`MiB`/`MB` (×1024²), optionally with `/s` (`64KiB`, `1MiB/s`).
pub fn parse_rate(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let t = t.strip_suffix("/s").unwrap_or(t).trim();
    let split = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let scale = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" | "kb" => 1024.0,
        "m" | "mib" | "mb" => 1024.0 * 1024.0,
        _ => {
            return Err(format!(
                "'{s}': the unit must be KiB or MiB per second (e.g. 64KiB, 1MiB) or none (bytes)"
            ));
        }
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a rate: write e.g. 64KiB, 1MiB or 65536"))?;
    if !(value.is_finite() && value >= 0.0) {
        return Err(format!("'{s}' must be a finite rate of 0 or more"));
    }
    Ok((value * scale).round() as u64)
}

/// Default `--max-inflight-body-mb`: one maximum-size body (128 MiB) plus room for small
/// ones, so 8 concurrent maximum uploads stay under 300 MB of resident memory
/// (BENCHMARKS.md, "Concurrent uploads").
pub const DEFAULT_MAX_INFLIGHT_BODY_MB: usize = 160;

/// Default `--max-deviation-mm`: 5 mm. A finishing allowance is tenths of a mm and a
/// machine's error under a millimetre; a probe reading 5 mm off the nominal is a wrong
/// part, a wrong datum or a flyer, not a machining error to compensate.
pub const DEFAULT_MAX_DEVIATION_MM: f64 = 5.0;

/// Default `--max-tangential-mm`: 0.5 mm. A probe touches the surface along its normal at
/// the nominal point, so the measured point lies off the nominal along the normal; the
/// tangential part is the probing position error (micrometres on a machine tool) plus
/// stylus-tip lateral deflection (well under 0.1 mm). A point paired with the wrong nominal
/// (a reversed or shifted upload) is off by at least one grid spacing.
pub const DEFAULT_MAX_TANGENTIAL_MM: f64 = 0.5;

impl Config {
    /// A configuration with every default, serving `addr` from `data_dir` (tests, benches).
    pub fn new(addr: SocketAddr, data_dir: PathBuf) -> Self {
        Config {
            addr,
            data_dir,
            database_url: None,
            database_password_file: None,
            tokens: None,
            tokens_file: None,
            read_token_concurrency: 1,
            demo: false,
            workers: None,
            queue: 32,
            max_body_bytes: DEFAULT_MAX_BODY_BYTES,
            body_timeout_s: 30.0,
            header_timeout_s: DEFAULT_HEADER_TIMEOUT_S,
            min_body_rate: DEFAULT_MIN_BODY_RATE,
            shutdown_grace_s: 30,
            lease_s: 10.0,
            db_wait_s: 0.0,
            max_inflight_body_mb: DEFAULT_MAX_INFLIGHT_BODY_MB,
            max_deviation_mm: DEFAULT_MAX_DEVIATION_MM,
            max_tangential_mm: DEFAULT_MAX_TANGENTIAL_MM,
            job_retention: DEFAULT_JOB_RETENTION,
            job_timeout: DEFAULT_JOB_TIMEOUT,
        }
    }

    /// The URL to connect to the database with: `--database-url` with the password of
    /// `--database-password-file` put in (the file is read now). `None`: SQLite in the data
    /// dir.
    pub fn database_url_with_password(&self) -> Result<Option<String>, ConfigError> {
        database_url_with_password(
            self.database_url.as_deref(),
            self.database_password_file.as_deref(),
        )
    }

    /// The tokens setting to load: `--tokens` as given (a file's path or inline entries),
    /// or the text of `--tokens-file` (read now). `None`: no tokens.
    pub fn tokens_text(&self) -> Result<Option<String>, ConfigError> {
        match (&self.tokens_file, &self.tokens) {
            (Some(path), _) => read_secret_file(path, "tokens").map(Some),
            (None, spec) => Ok(spec.clone()),
        }
    }

    /// Number of worker threads to use.
    pub fn worker_count(&self) -> usize {
        self.workers
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()))
            .max(1)
    }
}

/// A setting that names a file (a secret) that cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The file cannot be read (missing, no permission, not UTF-8).
    #[error(
        "cannot read the {what} file {} (check the path and that the service's user may \
         read it)",
        path.display()
    )]
    Unreadable {
        /// What the file holds (`tokens`, `database password`).
        what: &'static str,
        /// The file named.
        path: PathBuf,
        /// Why it cannot be read.
        #[source]
        source: std::io::Error,
    },
    /// The file holds nothing but line ends.
    #[error(
        "the {what} file {} is empty; write the {what} into it (a trailing newline is ignored)",
        path.display()
    )]
    Empty {
        /// What the file should hold.
        what: &'static str,
        /// The file named.
        path: PathBuf,
    },
    /// A password file without a PostgreSQL URL to put it into.
    #[error(
        "--database-password-file (TRUECUT_DATABASE_PASSWORD_FILE) needs --database-url \
         (DATABASE_URL) of PostgreSQL naming the user, e.g. postgres://truecut@db:5432/truecut \
         (SQLite has no password)"
    )]
    PasswordWithoutPostgres,
    /// The URL names no user for the password.
    #[error(
        "the database URL names no user for the password of --database-password-file: write \
         postgres://USER@HOST/DATABASE"
    )]
    NoUser,
    /// The URL holds a password already.
    #[error(
        "the database URL holds a password and --database-password-file gives one too: drop \
         the password from the URL (postgres://USER@HOST/DATABASE)"
    )]
    PasswordTwice,
}

/// Reads a secret from `path`: the file's text without its trailing line ends (`\n`,
/// `\r\n`); `what` names it in errors. An empty secret is an error.
pub fn read_secret_file(path: &Path, what: &'static str) -> Result<String, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Unreadable {
        what,
        path: path.to_path_buf(),
        source,
    })?;
    let secret = text.trim_end_matches(['\n', '\r']);
    if secret.is_empty() {
        return Err(ConfigError::Empty {
            what,
            path: path.to_path_buf(),
        });
    }
    Ok(secret.to_string())
}

/// `url` with the password read from `password_file` put in as the user's password
/// (percent-encoded), or `url` unchanged without a file. The URL must be PostgreSQL's and
/// name a user but no password.
pub fn database_url_with_password(
    url: Option<&str>,
    password_file: Option<&Path>,
) -> Result<Option<String>, ConfigError> {
    let Some(path) = password_file else {
        return Ok(url.map(str::to_string));
    };
    let Some(url) = url else {
        return Err(ConfigError::PasswordWithoutPostgres);
    };
    let password = read_secret_file(path, "database password")?;
    insert_password(url, &password).map(Some)
}

/// Puts `password` into the user part of a `postgres://USER@HOST...` URL.
pub fn insert_password(url: &str, password: &str) -> Result<String, ConfigError> {
    let rest = url
        .strip_prefix("postgres://")
        .or_else(|| url.strip_prefix("postgresql://"))
        .ok_or(ConfigError::PasswordWithoutPostgres)?;
    let scheme = &url[..url.len() - rest.len()];
    let authority_end = rest.find(['/', '?', '#']).unwrap_or(rest.len());
    let (authority, tail) = rest.split_at(authority_end);
    let (user, host) = authority.rsplit_once('@').ok_or(ConfigError::NoUser)?;
    if user.is_empty() {
        return Err(ConfigError::NoUser);
    }
    if user.contains(':') {
        return Err(ConfigError::PasswordTwice);
    }
    Ok(format!(
        "{scheme}{user}:{}@{host}{tail}",
        percent_encode(password)
    ))
}

/// RFC 3986 percent-encoding of every byte but the unreserved characters (`A-Z a-z 0-9 - .
/// _ ~`): safe in a URL's user information whatever the password holds.
fn percent_encode(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for b in text.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~') {
            out.push(char::from(b));
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

#[cfg(test)]
mod tests;
