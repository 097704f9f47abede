//! Persistence: the only user of sqlx and `std::fs`.
//!
//! Records live in SQLite (default, a file in the data dir) or PostgreSQL (a `postgres://`
//! URL), through one `sqlx::AnyPool` with runtime queries that run on both. Arrays of
//! numbers (surface grids, deviations) are stored as little-endian `f64` BLOBs: measured
//! about 10x faster than a row per point for 250,000-point uploads (BENCHMARKS.md).
//! Trained models are files under `<data-dir>/models`, see [`ModelStore`].

mod codec;
mod database;
mod docs;
mod iso230;
mod jobs;
mod machines;
mod measurements;
mod models;
mod surfaces;

pub use codec::{decode_f64s, decode_points, encode_f64s, encode_points};
pub use database::{Backend, Store};
pub use iso230::Iso230Run;
pub use jobs::{CancelOutcome, JobRecord};
pub use machines::MachineSummary;
pub use measurements::{Measurement, MeasurementSummary};
pub use models::{MODEL_FORMAT_VERSION, ModelStore, is_valid_id};
pub use surfaces::{Surface, SurfaceSummary};
