//! truecut: makes CNC machine tools cut closer to the drawing.
//!
//! A long-running REST service (and CLI) that keeps, per machine and per surface,
//! probe measurements and trained models, and computes machining-error
//! decompositions, compensations and error predictions from them.
//!
//! # Layout
//!
//! - [`api`]: HTTP translation: router, one file per resource, problem+json errors, auth, extractors.
//! - [`store`]: the only user of sqlx and `std::fs`: records (SQLite or PostgreSQL) and model files.
//! - [`jobs`]: bounded worker pool for CPU-heavy work off the async runtime, with progress and back-pressure.
//! - [`config`]: the service configuration (flags and environment, one struct).
//! - [`server`]: starts the HTTP service (store, jobs, router, listener) and shuts it down gracefully.
//! - [`cli`]: command-line entry points: `serve` (with `--demo`) and one subcommand per capability.

pub mod api;
pub mod cli;
pub mod config;
pub mod jobs;
pub mod server;
pub mod store;
