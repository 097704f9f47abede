//! The dashboard and the spec: `GET /` (the page), `GET /assets/{file}` (its script, styles
//! and plotting module) and `GET /openapi.yaml`.
//!
//! Everything is compiled into the binary (`include_str!` of `assets/` and `openapi.yaml`),
//! so the page works on an air-gapped shop network: nothing is fetched from anywhere but
//! this server, and the Content-Security-Policy sent with every asset forbids the browser
//! to try. The page draws its plots itself as SVG (`assets/plot.js`) from the `/v1` API.
//!
//! Auth: with tokens configured, `/` and `/assets/` need role `read` like any GET (see
//! `auth.rs`): a browser opening `/` gets `401` with `WWW-Authenticate: Basic`, the
//! operator types any user name and the token as the password, and the browser then sends
//! those credentials with the page's own `/v1` requests. `/openapi.yaml` is public, like
//! `/healthz`: the spec holds no shop data.

use axum::Router;
use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;

use super::AppState;
use super::error::ApiError;

/// The API description, served as is.
pub const OPENAPI_YAML: &str = include_str!("../../openapi.yaml");

const INDEX_HTML: &str = include_str!("../../assets/index.html");

/// The files under `/assets/`: name, media type, content.
const ASSETS: [(&str, &str, &str); 7] = [
    (
        "style.css",
        "text/css; charset=utf-8",
        include_str!("../../assets/style.css"),
    ),
    (
        "plot.js",
        "text/javascript; charset=utf-8",
        include_str!("../../assets/plot.js"),
    ),
    (
        "app.js",
        "text/javascript; charset=utf-8",
        include_str!("../../assets/app.js"),
    ),
    (
        "views.js",
        "text/javascript; charset=utf-8",
        include_str!("../../assets/views.js"),
    ),
    (
        "motion.js",
        "text/javascript; charset=utf-8",
        include_str!("../../assets/motion.js"),
    ),
    (
        "iso.js",
        "text/javascript; charset=utf-8",
        include_str!("../../assets/iso.js"),
    ),
    (
        "cam.js",
        "text/javascript; charset=utf-8",
        include_str!("../../assets/cam.js"),
    ),
];

/// Only this server's own scripts, styles and API; no inline script, nothing remote.
const CSP: &str = "default-src 'none'; script-src 'self'; style-src 'self'; \
                   connect-src 'self'; img-src 'self' data:; base-uri 'none'; form-action 'none'; \
                   frame-ancestors 'none'";

/// Routes of this resource.
pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/", get(index))
        .route("/assets/{file}", get(asset))
        .route("/openapi.yaml", get(openapi))
}

fn page(media_type: &'static str, body: &'static str) -> Response {
    let mut resp = body.into_response();
    let h = resp.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(media_type));
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    // The assets change with the binary; a revalidation is cheap on a shop network.
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    resp
}

/// `GET /`: the dashboard page.
async fn index() -> Response {
    page("text/html; charset=utf-8", INDEX_HTML)
}

/// `GET /assets/{file}`: one of the page's embedded files, else 404.
async fn asset(Path(file): Path<String>) -> Response {
    match ASSETS.iter().find(|(name, _, _)| *name == file) {
        Some((_, media_type, body)) => page(media_type, body),
        None => ApiError::not_found(format!(
            "no dashboard asset '{file}'; the assets are {}",
            ASSETS.map(|(n, _, _)| n).join(", ")
        ))
        .into_response(),
    }
}

/// `GET /openapi.yaml`: the spec this binary was built with.
async fn openapi() -> Response {
    let mut resp = OPENAPI_YAML.into_response();
    resp.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/yaml; charset=utf-8"),
    );
    resp
}
