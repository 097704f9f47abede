//! `truecut compensation MACHINE SURFACE --measurement ID`: fetches the compensated points of
//! a stored measurement from a running service and writes them to stdout (CSV
//! `x,y,z,i,j,k,offset` by default, or the JSON answer).

use reqwest::Method;
use reqwest::header::ACCEPT;

use super::client::{Client, ServerArgs};

/// Fetch the compensated points of a measurement (nominal − systematic error × normal).
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  truecut compensation --server http://127.0.0.1:8080 demo saddle --measurement demo-1 > points.csv\n  \
    truecut compensation demo saddle --measurement demo-1 --nu 121 --nv 121 --cl --format json > dense.json"
)]
pub struct Args {
    /// Where the service is.
    #[command(flatten)]
    pub server: ServerArgs,
    /// Machine id.
    pub machine: String,
    /// Surface id.
    pub surface: String,
    /// Measurement id.
    #[arg(long)]
    pub measurement: String,
    /// Output format.
    #[arg(long, value_parser = ["csv", "json"], default_value = "csv")]
    pub format: String,
    /// Resample the compensated surface at nu × nv points (with --nv).
    #[arg(long, requires = "nv")]
    pub nu: Option<usize>,
    /// See --nu.
    #[arg(long, requires = "nu")]
    pub nv: Option<usize>,
    /// Add compensated ball-end cutter-location points.
    #[arg(long)]
    pub cl: bool,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let client = Client::new(&args.server)?;
    let mut query = vec![("measurement", args.measurement.clone())];
    if let (Some(nu), Some(nv)) = (args.nu, args.nv) {
        query.push(("nu", nu.to_string()));
        query.push(("nv", nv.to_string()));
    }
    if args.cl {
        query.push(("cl", "true".into()));
    }
    let accept = if args.format == "csv" {
        "text/csv"
    } else {
        "application/json"
    };
    let path = format!(
        "/v1/machines/{}/surfaces/{}/compensation",
        args.machine, args.surface
    );
    let rb = client
        .request(Method::GET, &path)
        .query(&query)
        .header(ACCEPT, accept);
    let body = client
        .runtime
        .block_on(async { anyhow::Ok(client.send(rb).await?.bytes().await?) })?;
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(&body)?;
    if !body.ends_with(b"\n") {
        out.write_all(b"\n")?;
    }
    Ok(())
}
