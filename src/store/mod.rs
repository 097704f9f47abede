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
mod jobs;
mod machines;
mod measurements;
mod models;
mod storage;
mod surfaces;

pub use codec::{decode_f64s, decode_points, encode_f64s, encode_points};
pub use database::{Backend, Store};
pub use jobs::{CancelOutcome, JobRecord};
pub use machines::MachineSummary;
pub use measurements::{Measurement, MeasurementSummary};
pub use models::{MODEL_FORMAT_VERSION, ModelStore, is_valid_id};
pub use storage::{
    StorageFailure, StorageState, check_data_dir, free_bytes, probe_writable, state_of,
    storage_failure,
};
pub use surfaces::{Surface, SurfaceSummary};
