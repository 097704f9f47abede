//! The HTTP end-to-end suites as one test binary (one link instead of ten). Each module
//! except `step_network` (the network on the study's surfaces) boots the real server
//! through `helpers::spawn_app`, most on both backends with `on_both_backends!` (the
//! PostgreSQL variants print SKIPPED without `TRUECUT_TEST_PG`). Run one suite with
//! `cargo test --test api contour::`.

// First, so that `on_both_backends!` is visible in every module below.
#[macro_use]
mod helpers;

mod cli_client;
mod compensated;
mod contour;
mod crash;
mod dashboard;
mod decomposition;
mod gap;
mod hardening;
mod instances;
mod iso230;
mod iso230_comp;
mod iso230_trace;
mod jobs_cancel;
mod jobs_models;
mod jobs_storage;
mod resources;
mod scale_out;
mod service;
mod stalled;
mod step_error;
mod step_network;
mod volumetric;
