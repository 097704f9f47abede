//! The `truecut` binary: parse the command line, start telemetry, dispatch.
#![warn(missing_docs)]

use clap::Parser;

/// Exit codes: 0 success, 2 usage (clap), the others as `truecut --help` lists them.
fn main() -> std::process::ExitCode {
    let cli = truecut::cli::Cli::parse();
    truecut::cli::init_tracing(cli.log_format);
    match truecut::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::from(truecut::cli::exit_code(&e))
        }
    }
}
