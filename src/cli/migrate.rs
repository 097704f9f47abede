//! `truecut migrate`: apply the database migrations of this release and say what was applied,
//! the step a rolling upgrade takes before it replaces the instances (the `migrate` service of
//! deploy/migrate.yaml, added to compose.yaml's fleet). `serve` applies them too; running
//! this first means no new instance changes the schema under old ones, and a migration that
//! fails stops the upgrade before any instance is replaced.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;

use crate::store::MigrationReport;

/// Apply the database migrations this release knows and print what was applied. Versions the
/// database holds that this release does not know (a newer release's) are left alone and named.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Data directory of the embedded SQLite database (when there is no --database-url).
    #[arg(long, default_value = "./truecut-data", env = "TRUECUT_DATA_DIR")]
    pub data_dir: PathBuf,
    /// Database URL: `sqlite://FILE` or `postgres://...` (as `truecut serve`).
    #[arg(long, env = "DATABASE_URL")]
    pub database_url: Option<String>,
    /// File holding the database password, put into --database-url (as `truecut serve`).
    #[arg(long, env = "TRUECUT_DATABASE_PASSWORD_FILE")]
    pub database_password_file: Option<PathBuf>,
    /// Seconds to wait for a database that does not answer yet (as `truecut serve`).
    #[arg(long, default_value_t = 0.0, env = "TRUECUT_DB_WAIT_S")]
    pub db_wait_s: f64,
}

/// Applies the migrations and prints the report on stdout.
pub fn run(args: Args) -> anyhow::Result<()> {
    let url = crate::config::database_url_with_password(
        args.database_url.as_deref(),
        args.database_password_file.as_deref(),
    )?;
    let wait = Duration::try_from_secs_f64(args.db_wait_s).map_err(|_| {
        anyhow::anyhow!(
            "--db-wait-s must be a number of seconds >= 0, got {}",
            args.db_wait_s
        )
    })?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let report = runtime.block_on(crate::store::migrate(&args.data_dir, url.as_deref(), wait))?;
    let mut out = std::io::stdout().lock();
    out.write_all(describe(&report).as_bytes())
        .context("cannot write to stdout")?;
    Ok(())
}

/// The report as lines: one per applied migration, then the database's state.
pub fn describe(report: &MigrationReport) -> String {
    let mut text = String::new();
    for (version, name) in &report.applied {
        text.push_str(&format!("applied {version:04} {name}\n"));
    }
    if report.applied.is_empty() {
        text.push_str(&format!(
            "nothing to apply: the database has every migration of this release (up to {:04})\n",
            report.latest_known
        ));
    } else {
        text.push_str(&format!(
            "the database is at migration {:04}\n",
            report.latest_known
        ));
    }
    if !report.unknown.is_empty() {
        let versions: Vec<String> = report.unknown.iter().map(|v| format!("{v:04}")).collect();
        text.push_str(&format!(
            "left alone: {} (applied by a newer release; this one serves on them)\n",
            versions.join(", ")
        ));
    }
    text
}
