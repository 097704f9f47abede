//! truecut: makes CNC machine tools cut closer to the drawing.
//!
//! A long-running REST service (and CLI) that keeps, per machine and per surface,
//! probe measurements and trained models, and computes machining-error
//! decompositions, compensations and error predictions from them.
//!
//! # Layout
//!
//! The shape, the invariants and the dependency rules are in `ARCHITECTURE.md` at the
//! repository root (checked by `tests/tidy.rs`); citations resolve in `docs/REFERENCES.md`.
//!
//! - [`api`]: HTTP translation: router, one file per resource, problem+json errors, auth, extractors.
//! - [`store`]: the only user of sqlx and `std::fs`: records (SQLite or PostgreSQL) and model files.
//! - [`jobs`]: bounded worker pool for CPU-heavy work off the async runtime, with progress and back-pressure.
//! - [`config`]: the service configuration (flags and environment, one struct).
//! - [`server`]: starts the HTTP service (store, jobs, router, listener) and shuts it down gracefully.
//! - [`cli`]: command-line entry points: `serve` (with `--demo`), one subcommand per capability, and the client commands of a running service (upload, compensation, jobs, iso230-2/-4).
//! - [`numeric`]: the toolbox every core may use: Brent line search, tridiagonal solve, B-spline basis, difference penalties, least squares, vec3, thread splitting.
//! - [`geometry`]: cubic splines, height surfaces, iso-parametric path sampling, exact ball-end step error (Zhang et al. 2023) and its network features.
//! - [`nn`]: small dense networks (MLP): z-score, dropout, SGD-momentum/Adam, early stopping, binary model format (Zhang et al. 2023; Xiang et al. 2019; Wang, Dai & Hong).
//! - [`volumetric`]: volumetric error maps (Xiang et al. 2019 and Wang, Dai & Hong): trilinear table, 3-8-3 network, ISO 230-1 rigid-body model, hybrid, auto by CV, compensation tables.
//! - [`cam`]: compensated programs for CAM post-processors: volumetric pre-compensation of G-code and CL points, re-emission keeping the post's structure, contour pre-distortion.
//! - [`motion`]: contour error from G-code (Zhang & Chen 2025): G-code reader, RTCP interpolation, kinematics, servo cascade, contour error.
//! - [`signal`]: machining-error decomposition (Chen et al. 2024): VMD, EMD, wavelets, Whittaker smoothing, screening, coarse-to-fine in 1-D and on 2-D grids.
//! - [`compensation`]: normal-offset compensation (Chen et al. 2024): compensated points, reconstructed compensated surface, compensated CL points.
//! - [`gap`]: sim-to-real gap diagnosis (motion and part): effects library re-simulated, localisation, blocked-CV selection, self-check; the motion-gap request.
//! - [`step_error`]: step error as a capability: flat segment batches solved on all cores, network training and the model file's metadata.
//! - [`codec`]: hand-written fast decoders for large bodies (step-error segment batches), with their own error.
//! - [`metrology`]: ISO 230-2 positioning accuracy and repeatability (table or logged run) and ISO 230-4 circular tests (orthogonal least-squares circle, G, F, H).
//! - [`wire`]: serde types of the HTTP bodies that both the server and the CLI use.

// Every public item says what it is (units for numbers); CI's clippy -D warnings makes it an
// error.
#![warn(missing_docs)]

pub mod api;
pub mod cam;
pub mod cli;
pub mod codec;
pub mod compensation;
pub mod config;
pub mod gap;
pub mod geometry;
pub mod jobs;
pub mod metrology;
pub mod motion;
pub mod nn;
pub mod numeric;
pub mod server;
pub mod signal;
pub mod step_error;
pub mod store;
pub mod volumetric;
pub mod wire;

/// The version of truecut that computed an answer, as `truecut_version` in decomposition,
/// gap-diagnosis and volumetric-map answers and in stored job results (issue 25: the same
/// input and version give the same bits): the package version, then `+` and the git commit
/// when the build had it in the environment variable `TRUECUT_GIT_COMMIT` (`.ci/run` and the
/// Dockerfile pass it; no build script, so a build without git still builds), e.g.
/// `0.1.0+3e77321`.
pub fn version() -> &'static str {
    static VERSION: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    VERSION.get_or_init(|| match option_env!("TRUECUT_GIT_COMMIT") {
        Some(commit) if !commit.trim().is_empty() => {
            format!("{}+{}", env!("CARGO_PKG_VERSION"), commit.trim())
        }
        _ => env!("CARGO_PKG_VERSION").to_string(),
    })
}
