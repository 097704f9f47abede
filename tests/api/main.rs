//! The HTTP end-to-end suites as one test binary (one link instead of ten). Each module
//! except `step_network` (the network on the study's surfaces) and `pg_tls` (the store and
//! the binary against the TLS-only cluster of `.ci/pg_tls.sh`) boots the real server
//! through `helpers::spawn_app`, most on both backends with `on_both_backends!` (the
//! PostgreSQL variants print SKIPPED without `TRUECUT_TEST_PG`). Run one suite with
//! `cargo test --test api contour::`.

// First, so that `on_both_backends!` is visible in every module below.
#[macro_use]
mod helpers;

mod blind_plant;
mod bounded;
mod cam_stop;
mod cli_client;
mod cli_program;
mod compensated;
mod contour;
mod crash;
mod dashboard;
mod decomposition;
mod door;
mod effects;
mod faults;
mod fleet;
mod fleet_files;
mod fleet_start;
mod gap;
mod hardening;
mod idempotency;
mod instances;
mod iso230;
mod iso230_comp;
mod iso230_trace;
mod jobs_cancel;
mod jobs_models;
mod jobs_storage;
mod observability;
mod pg_tls;
mod proxy;
mod resources;
mod scale_out;
mod service;
mod stalled;
mod step_error;
mod step_network;
mod volumetric;

// LinuxCNC's interpreter and the validity check of compensated programs, shared with the
// G-code oracle's binary (this one does not use all of them).
#[allow(dead_code)]
#[path = "../gcode_oracle/rs274.rs"]
mod rs274;
#[allow(dead_code)]
#[path = "../gcode_oracle/valid.rs"]
mod valid;
