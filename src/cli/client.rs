//! The HTTP client the CLI's client commands share: where the service is (`--server`,
//! `--token`), one request helper that turns every failure into an exit code, and the exit
//! codes themselves ([`EXIT_CODES`], printed by `truecut --help`).
//!
//! TLS is rustls on the `ring` provider (installed here: reqwest is built without a default
//! provider, see Cargo.toml); plain `http://` needs none.

use std::time::Duration;

use anyhow::anyhow;
use reqwest::{Method, RequestBuilder, Response, StatusCode};

/// The exit codes, as `truecut --help` prints them.
pub const EXIT_CODES: &str = "Exit codes: 0 success; 1 local failure (a file cannot be read or \
    parsed); 2 usage error (bad flags or arguments); 3 the server refused the request (4xx: \
    its sentence says what to fix); 4 the server cannot be reached, timed out or failed (5xx); \
    5 a followed job failed or was cancelled.";

/// Why a command failed, with the process exit code it maps to.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ClientError {
    /// The server answered 4xx (exit 3).
    #[error("the server refused the request ({status}): {detail}")]
    Refused {
        /// The HTTP status.
        status: u16,
        /// The problem+json detail (or the body).
        detail: String,
    },
    /// The server could not be reached, timed out or answered 5xx (exit 4).
    #[error("{0}")]
    Unavailable(String),
    /// A followed job ended failed or cancelled (exit 5).
    #[error("job {id} ended {state}: {error}")]
    JobFailed {
        /// Job id.
        id: String,
        /// `failed` or `cancelled`.
        state: String,
        /// The job's error sentence.
        error: String,
    },
}

impl ClientError {
    /// The process exit code.
    pub fn exit_code(&self) -> u8 {
        match self {
            ClientError::Refused { .. } => 3,
            ClientError::Unavailable(_) => 4,
            ClientError::JobFailed { .. } => 5,
        }
    }
}

/// The exit code for a command's error: the [`ClientError`]'s code anywhere in the chain,
/// else 1.
pub fn exit_code(err: &anyhow::Error) -> u8 {
    err.chain()
        .find_map(|e| e.downcast_ref::<ClientError>())
        .map_or(1, ClientError::exit_code)
}

/// Where the service is and how to authenticate.
#[derive(Clone, Debug, clap::Args)]
pub struct ServerArgs {
    /// Base URL of a running `truecut serve` (http or https).
    #[arg(long, env = "TRUECUT_SERVER", default_value = "http://127.0.0.1:8080")]
    pub server: String,
    /// Bearer token (a line of the server's --tokens file).
    #[arg(long, env = "TRUECUT_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Give up on a request after this many seconds.
    #[arg(long, default_value_t = 300)]
    pub timeout_s: u64,
}

/// A connected client: base URL, token, reqwest client and a current-thread runtime.
pub struct Client {
    base: String,
    token: Option<String>,
    http: reqwest::Client,
    /// The runtime the requests run on (commands `block_on` it).
    pub runtime: tokio::runtime::Runtime,
}

/// Installs rustls' `ring` provider as the process default (once; later calls do nothing).
/// reqwest is built without a provider, so this must run before a client is built.
pub fn install_crypto_provider() {
    let _ = rustls::crypto::ring::default_provider().install_default();
}

impl Client {
    /// A client for `args` (checks that the URL is http or https).
    pub fn new(args: &ServerArgs) -> anyhow::Result<Client> {
        let base = args.server.trim_end_matches('/').to_string();
        if !(base.starts_with("http://") || base.starts_with("https://")) {
            anyhow::bail!(
                "--server '{}' must start with http:// or https:// (e.g. http://127.0.0.1:8080)",
                args.server
            );
        }
        install_crypto_provider();
        let http = reqwest::Client::builder()
            .timeout(Duration::from_secs(args.timeout_s.max(1)))
            .connect_timeout(Duration::from_secs(10))
            .user_agent(concat!("truecut-cli/", env!("CARGO_PKG_VERSION")))
            .build()?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        Ok(Client {
            base,
            token: args.token.clone(),
            http,
            runtime,
        })
    }

    /// The full URL of `path` (which starts with `/`).
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// A request to `path` with the token.
    pub fn request(&self, method: Method, path: &str) -> RequestBuilder {
        let rb = self.http.request(method, self.url(path));
        match &self.token {
            Some(t) => rb.bearer_auth(t),
            None => rb,
        }
    }

    /// Sends `rb`; a 2xx response comes back, anything else becomes a [`ClientError`].
    pub async fn send(&self, rb: RequestBuilder) -> anyhow::Result<Response> {
        let resp = rb.send().await.map_err(|e| self.transport(e))?;
        check(resp).await
    }

    /// A transport failure as [`ClientError::Unavailable`] naming the server.
    pub fn transport(&self, e: reqwest::Error) -> anyhow::Error {
        let what = if e.is_timeout() {
            "timed out"
        } else if e.is_connect() {
            "cannot be reached (is `truecut serve` running there?)"
        } else {
            "failed"
        };
        let mut cause = String::new();
        let mut src: Option<&dyn std::error::Error> = Some(&e);
        while let Some(s) = src {
            cause.push_str(": ");
            cause.push_str(&s.to_string());
            src = s.source();
        }
        ClientError::Unavailable(format!("the server at {} {what}{cause}", self.base)).into()
    }
}

/// A 2xx response as is; 4xx as [`ClientError::Refused`] with the problem's detail; 5xx and
/// anything else as [`ClientError::Unavailable`].
pub async fn check(resp: Response) -> anyhow::Result<Response> {
    let status = resp.status();
    if status.is_success() {
        return Ok(resp);
    }
    let text = resp.text().await.unwrap_or_default();
    let detail = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v.get("detail").and_then(|d| d.as_str()).map(str::to_string))
        .unwrap_or(text);
    if status.is_client_error() {
        Err(ClientError::Refused {
            status: status.as_u16(),
            detail,
        }
        .into())
    } else if status == StatusCode::SERVICE_UNAVAILABLE || status.is_server_error() {
        Err(ClientError::Unavailable(format!("the server failed ({status}): {detail}")).into())
    } else {
        Err(anyhow!("unexpected answer {status}: {detail}"))
    }
}

/// Whether stderr is a terminal (progress bars) or not (quiet lines).
pub fn interactive() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal()
}
