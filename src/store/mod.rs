//! Persistence: the only user of sqlx and `std::fs`.
//!
//! Records live in SQLite (default, a file in the data dir) or PostgreSQL (a `postgres://`
//! URL), through one `sqlx::AnyPool` with runtime queries that run on both. Arrays of
//! numbers (surface grids, deviations) are stored as little-endian `f64` BLOBs: measured
//! about 10x faster than a row per point for 250,000-point uploads (BENCHMARKS.md).
//! Trained models are versioned: in the database on PostgreSQL (every instance serves
//! them), files under `<data-dir>/models` on SQLite; see [`ModelStore`]. Instances sharing
//! the database keep leases in `instances` (`instances.rs`).

mod codec;
mod connect_error;
mod database;
mod docs;
mod idempotency;
mod instances;
mod iso230;
mod job_list;
mod jobs;
mod legacy_models;
mod machines;
mod measurements;
mod migrations;
mod model_versions;
mod models;
mod outage;
mod storage;
mod surface_cache;
mod surfaces;

pub use codec::{decode_f64s, decode_points, encode_f64s, encode_points};
pub use connect_error::{ConnectError, TlsProblem};
pub use database::{Backend, DatabaseReport, PoolReport, Store, migrate};
pub use idempotency::{Claim, IDEMPOTENCY_KEEP, IN_FLIGHT_STALE, KeptAnswer};
pub use instances::{LeaseReport, Reaped};
pub use iso230::Iso230Run;
pub use job_list::JobBytes;
pub use jobs::{CancelOutcome, ClaimedJob, JobRecord, MAX_CLAIMS};
pub use machines::MachineSummary;
pub use measurements::{Inserted, Measurement, MeasurementSummary};
pub use migrations::MigrationReport;
pub use model_versions::{ModelVersion, ModelVersions, Rollback};
pub use models::{JobDone, MODEL_FORMAT_VERSION, ModelStore, VERSIONS_KEPT, is_valid_id};
pub use outage::{DatabaseOutage, database_outage};
pub use storage::{
    StorageFailure, StorageState, check_data_dir, free_bytes, probe_writable, state_of,
    storage_failure,
};
pub use surfaces::{Surface, SurfaceSummary};
