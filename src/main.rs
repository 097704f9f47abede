//! The `truecut` binary: parse the command line, start telemetry, dispatch.
#![warn(missing_docs)]

use clap::Parser;

fn main() -> anyhow::Result<()> {
    let cli = truecut::cli::Cli::parse();
    truecut::cli::init_tracing();
    truecut::cli::run(cli)
}
