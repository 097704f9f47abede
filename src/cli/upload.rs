//! `truecut upload MACHINE SURFACE FILE`: sends a probe measurement (CSV or JSON) to a running
//! service, with a progress bar on a terminal and quiet lines when piped, and prints the new
//! measurement id on stdout (so a script can capture it).

use std::path::PathBuf;

use anyhow::Context;
use bytes::Bytes;
use indicatif::{ProgressBar, ProgressStyle};
use reqwest::Method;
use reqwest::header::{CONTENT_LENGTH, CONTENT_TYPE};

use super::client::{Client, ServerArgs, interactive};

/// Upload a probe measurement of a surface to a running service.
///
/// The file is CSV (header `x,y,z` or `deviation`, optionally after a point-id column; comma,
/// semicolon or tab) or JSON (`{"points": [...]}` or `{"deviations": [...]}`), in the
/// surface's nominal order. Prints the stored measurement's id on stdout.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  truecut upload --server http://127.0.0.1:8080 demo saddle probe.csv\n  \
    ID=$(truecut upload --token $T demo saddle probe.csv) && echo \"stored $ID\""
)]
pub struct Args {
    /// Where the service is.
    #[command(flatten)]
    pub server: ServerArgs,
    /// Machine id.
    pub machine: String,
    /// Surface id.
    pub surface: String,
    /// The measurement file (.csv or .json).
    pub file: PathBuf,
    /// Id to store it under (default: the server picks one).
    #[arg(long)]
    pub id: Option<String>,
}

/// Runs the upload.
pub fn run(args: Args) -> anyhow::Result<()> {
    let body = std::fs::read(&args.file)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    let json = args
        .file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let content_type = if json { "application/json" } else { "text/csv" };
    let client = Client::new(&args.server)?;
    let mut path = format!(
        "/v1/machines/{}/surfaces/{}/measurements",
        args.machine, args.surface
    );
    if let Some(id) = &args.id {
        path.push_str(&format!("?id={id}"));
    }
    let total = body.len() as u64;
    let tty = interactive();
    let bar = if tty {
        let bar = ProgressBar::new(total);
        bar.set_style(
            ProgressStyle::with_template(
                "{msg} [{bar:30}] {bytes}/{total_bytes} ({bytes_per_sec})",
            )?
            .progress_chars("=> "),
        );
        bar.set_message(format!("uploading {}", args.file.display()));
        bar
    } else {
        eprintln!(
            "uploading {} ({total} bytes) to {}",
            args.file.display(),
            client.url(&path)
        );
        ProgressBar::hidden()
    };
    let chunks: Vec<Bytes> = body.chunks(64 * 1024).map(Bytes::copy_from_slice).collect();
    let counter = bar.clone();
    let stream = futures::stream::iter(chunks.into_iter().map(move |c| {
        counter.inc(c.len() as u64);
        Ok::<Bytes, std::io::Error>(c)
    }));
    let rb = client
        .request(Method::POST, &path)
        .header(CONTENT_TYPE, content_type)
        .header(CONTENT_LENGTH, total)
        .body(reqwest::Body::wrap_stream(stream));
    let answer: serde_json::Value = client.runtime.block_on(async {
        let resp = client.send(rb).await;
        bar.finish_and_clear();
        anyhow::Ok(resp?.json().await?)
    })?;
    let id = answer["id"].as_str().unwrap_or_default();
    eprintln!(
        "stored measurement {id} of {}/{}: {} points, max |deviation| {} mm, mean {} mm",
        args.machine, args.surface, answer["n"], answer["max_abs"], answer["mean_abs"]
    );
    for w in answer["warnings"].as_array().into_iter().flatten() {
        eprintln!("warning: {}", w.as_str().unwrap_or_default());
    }
    println!("{id}");
    Ok(())
}
