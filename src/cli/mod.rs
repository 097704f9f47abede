//! Command-line entry points. Each subcommand lives in its own file with
//! `pub struct Args` (clap) and `pub fn run(args: Args) -> anyhow::Result<()>`. The client
//! commands (`upload`, `compensation`, `jobs`, `program`, `iso230-2`/`iso230-4` with `--server`) talk
//! to a running service through `client` and the bodies of `wire`; [`exit_code`] maps their
//! failures to the exit codes `truecut --help` lists.

pub mod client;
pub mod compensation;
pub mod contour;
pub mod decompose;
pub mod demo;
pub mod effects;
pub mod gap;
pub mod iso;
pub mod jobs;
pub mod migrate;
pub mod program;
pub mod serve;
pub mod step;
pub mod step_transfer;
pub mod upload;
pub mod volumetric;

use clap::{Parser, Subcommand};

/// truecut: makes CNC machine tools cut closer to the drawing.
#[derive(Debug, Parser)]
#[command(name = "truecut", version, about, after_help = client::EXIT_CODES)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
    /// Log line format on stderr: `text` (for a terminal) or `json` (one JSON object a line,
    /// for a log collector; spans such as a request's `request_id` and a job's `job` and
    /// `kind` are fields of every line logged inside them).
    #[arg(long, global = true, env = "TRUECUT_LOG_FORMAT", value_enum, default_value_t = LogFormat::Text)]
    pub log_format: LogFormat,
}

/// How log lines are written ([`Cli::log_format`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines.
    Text,
    /// One JSON object a line.
    Json,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Serve the REST API until SIGINT/SIGTERM (`--demo` loads a demo machine and surface).
    #[command(
        after_help = "Example:\n  truecut serve --demo --addr 127.0.0.1:8080 --data-dir ./truecut-data"
    )]
    Serve(crate::config::Config),
    /// Apply the database migrations of this release and print what was applied (the step
    /// before a rolling upgrade; `serve` applies them too, and serves on a database a newer
    /// release migrated).
    #[command(
        after_help = "Example:\n  truecut migrate --database-url postgres://truecut@db/truecut --database-password-file /run/secrets/db-password"
    )]
    Migrate(migrate::Args),
    /// Predict the contour error of a G-code program on a machine (machine JSON file or stored id).
    #[command(
        after_help = "Example:\n  truecut contour part.nc --machine machine.json --output answer.json"
    )]
    Contour(contour::Args),
    /// Split a machining error (CSV or JSON) into systematic and random parts (Chen et al. 2024).
    #[command(after_help = "Example:\n  truecut decompose errors.csv --grid 45,45 > parts.csv")]
    Decompose(decompose::Args),
    /// Sim-to-real gap diagnosis: `selfcheck`, `diagnose` (a motion body) or `csv` (a trace).
    #[command(
        after_help = "Example:\n  truecut gap selfcheck --cases 90\n  truecut gap diagnose --machine machine.json --body motion.json"
    )]
    Gap(gap::Args),
    /// Fit a volumetric error map to measured nodes (CSV), export a compensation table.
    #[command(after_help = "Example:\n  truecut volumetric --synthetic 7,6,5 > grid.csv")]
    Volumetric(volumetric::Args),
    /// Step error of ball-end toolpaths (Zhang et al. 2023): `exact`, `samples`, `train`,
    /// `predict`, `transfer`.
    #[command(after_help = "Example:\n  truecut step exact --help")]
    Step(step::Args),
    /// Upload a probe measurement (CSV or JSON) to a running service; prints the new id.
    Upload(upload::Args),
    /// Fetch the compensated points of a stored measurement from a running service (CSV).
    Compensation(compensation::Args),
    /// Compensate a G-code program on a running service: program to stdout, warnings to
    /// stderr (for a post-processor's pipeline).
    Program(program::Args),
    /// Background jobs of a running service: list, get (--wait), cancel, submit (--wait).
    Jobs(jobs::Args),
    /// ISO 230-2:2014 positioning accuracy and repeatability of an axis (table or logged run).
    #[command(name = "iso230-2")]
    Iso2302(iso::Args2),
    /// ISO 230-4:2005 circular test (G, F, H), or its simulation on a stored machine.
    #[command(name = "iso230-4")]
    Iso2304(iso::Args4),
    /// The effects stored with a machine on a running service: accept what a gap diagnosis
    /// found, show, versions, rollback.
    Effects(effects::Args),
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Serve(config) => serve::run(config),
        Command::Migrate(a) => migrate::run(a),
        Command::Contour(a) => contour::run(a),
        Command::Decompose(a) => decompose::run(a),
        Command::Gap(a) => gap::run(a),
        Command::Volumetric(a) => volumetric::run(a),
        Command::Step(a) => step::run(a),
        Command::Upload(a) => upload::run(a),
        Command::Compensation(a) => compensation::run(a),
        Command::Jobs(a) => jobs::run(a),
        Command::Program(a) => program::run(a),
        Command::Iso2302(a) => iso::run_2(a),
        Command::Iso2304(a) => iso::run_4(a),
        Command::Effects(a) => effects::run(a),
    }
}

/// The process exit code for a command's error (see [`client::EXIT_CODES`]).
pub fn exit_code(err: &anyhow::Error) -> u8 {
    client::exit_code(err)
}

/// Logs to stderr in `format`; level from `RUST_LOG` (default `info`, sqlx at `warn`).
pub fn init_tracing(format: LogFormat) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,sqlx=warn"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    let _ = match format {
        LogFormat::Text => builder.try_init(),
        // Spans flattened into each line's fields: a job's line names its request.
        LogFormat::Json => builder
            .json()
            .flatten_event(true)
            .with_current_span(true)
            .with_span_list(true)
            .try_init(),
    };
}
