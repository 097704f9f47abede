//! Command-line entry points. Each subcommand lives in its own file with
//! `pub struct Args` (clap) and `pub fn run(args: Args) -> anyhow::Result<()>`.

pub mod contour;
pub mod decompose;
pub mod demo;
pub mod gap;
pub mod serve;
pub mod step;
pub mod step_transfer;
pub mod volumetric;

use clap::{Parser, Subcommand};

/// truecut: makes CNC machine tools cut closer to the drawing.
#[derive(Debug, Parser)]
#[command(name = "truecut", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Serve the REST API until SIGINT/SIGTERM (`--demo` loads a demo machine and surface).
    Serve(crate::config::Config),
    /// Predict the contour error of a G-code program on a machine (machine JSON file or stored id).
    Contour(contour::Args),
    /// Split a machining error (CSV or JSON) into systematic and random parts (Chen et al. 2024).
    Decompose(decompose::Args),
    /// Sim-to-real gap diagnosis: `selfcheck`, `diagnose` (a motion body) or `csv` (a trace).
    Gap(gap::Args),
    /// Fit a volumetric error map to measured nodes (CSV), export a compensation table.
    Volumetric(volumetric::Args),
    /// Step error of ball-end toolpaths (Zhang et al. 2023): `exact`, `samples`, `train`,
    /// `predict`, `transfer`.
    Step(step::Args),
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Serve(config) => serve::run(config),
        Command::Contour(a) => contour::run(a),
        Command::Decompose(a) => decompose::run(a),
        Command::Gap(a) => gap::run(a),
        Command::Volumetric(a) => volumetric::run(a),
        Command::Step(a) => step::run(a),
    }
}

/// Logs to stderr; level from `RUST_LOG` (default `info`, sqlx at `warn`).
pub fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,sqlx=warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}
