//! `truecut effects ...`: the effects stored with a machine on a running service: `accept`
//! (adopt what a gap diagnosis found: the `accept` body of its answer, from a job or a saved
//! answer), `show`, `versions` and `rollback`. Answers are JSON on stdout.

use std::path::PathBuf;

use anyhow::{Context, bail};
use reqwest::Method;
use serde_json::{Value, json};

use super::client::{Client, ServerArgs};

/// The effects stored with a machine.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  truecut effects accept --server http://cnc-host:8080 mill-3 0193c1e2-...\n  \
    truecut effects accept mill-3 --answer diagnosis.json\n  \
    truecut effects versions mill-3\n  truecut effects rollback mill-3 2"
)]
pub struct Args {
    /// Where the service is.
    #[command(flatten)]
    pub server: ServerArgs,
    /// What to do.
    #[command(subcommand)]
    pub command: EffectsCommand,
}

/// `truecut effects` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum EffectsCommand {
    /// Store the effects a motion gap diagnosis found as the machine's (a new version): the
    /// `accept` of the job's result (followed to its end), or of a saved answer (--answer).
    #[command(
        after_help = "Example:\n  truecut effects accept mill-3 0193c1e2-7f00-7abc-8def-0123456789ab"
    )]
    Accept {
        /// Machine id.
        machine: String,
        /// The diagnosis job's id (leave out with --answer).
        job: Option<String>,
        /// A saved diagnosis answer (JSON file, `-` for stdin) instead of a job.
        #[arg(long, conflicts_with = "job")]
        answer: Option<PathBuf>,
    },
    /// The effects the machine serves now.
    #[command(after_help = "Example:\n  truecut effects show mill-3")]
    Show {
        /// Machine id.
        machine: String,
    },
    /// The kept versions, newest first, and the one served.
    #[command(after_help = "Example:\n  truecut effects versions mill-3")]
    Versions {
        /// Machine id.
        machine: String,
    },
    /// Serve a kept version from now on.
    #[command(after_help = "Example:\n  truecut effects rollback mill-3 2")]
    Rollback {
        /// Machine id.
        machine: String,
        /// The version (from `versions`).
        version: i64,
    },
}

fn call(
    client: &Client,
    method: Method,
    path: &str,
    body: Option<&Value>,
) -> anyhow::Result<Value> {
    let mut rb = client.request(method, path);
    if let Some(b) = body {
        rb = rb.json(b);
    }
    client
        .runtime
        .block_on(async { anyhow::Ok(client.send(rb).await?.json::<Value>().await?) })
}

/// The `accept` body of a diagnosis answer, its `source` naming where it came from.
fn accept_of(answer: &Value, from: &str) -> anyhow::Result<Value> {
    let Some(accept) = answer.get("accept") else {
        bail!(
            "{from} has no accept body: only a motion gap diagnosis (POST \
             /v1/machines/MACHINE/gap-diagnosis with \"domain\": \"motion\") answers one"
        );
    };
    let mut body = accept.clone();
    body["source"] = json!(format!(
        "{from} ({})",
        accept["source"].as_str().unwrap_or("gap diagnosis")
    ));
    Ok(body)
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let client = Client::new(&args.server)?;
    let answer = match args.command {
        EffectsCommand::Accept {
            machine,
            job,
            answer,
        } => {
            let body = match (job, answer) {
                (Some(id), None) => {
                    let result = super::jobs::follow(&client, &id)?;
                    accept_of(&result, &format!("gap-diagnosis job {id}"))?
                }
                (None, Some(path)) => {
                    let text = if path.as_os_str() == "-" {
                        std::io::read_to_string(std::io::stdin())
                            .context("cannot read the answer from stdin")?
                    } else {
                        std::fs::read_to_string(&path)
                            .with_context(|| format!("cannot read {}", path.display()))?
                    };
                    let a: Value = serde_json::from_str(&text)
                        .with_context(|| format!("{} is not JSON", path.display()))?;
                    accept_of(&a, &format!("the answer in {}", path.display()))?
                }
                _ => bail!("name the diagnosis: a JOB id, or --answer FILE with a saved answer"),
            };
            let n = body["effects"].as_array().map_or(0, Vec::len);
            let stored = call(
                &client,
                Method::PUT,
                &format!("/v1/machines/{machine}/effects"),
                Some(&body),
            )?;
            eprintln!(
                "machine {machine}: {n} effects stored as version {}",
                stored["version"]
            );
            stored
        }
        EffectsCommand::Show { machine } => call(
            &client,
            Method::GET,
            &format!("/v1/machines/{machine}/effects"),
            None,
        )?,
        EffectsCommand::Versions { machine } => call(
            &client,
            Method::GET,
            &format!("/v1/machines/{machine}/effects/versions"),
            None,
        )?,
        EffectsCommand::Rollback { machine, version } => call(
            &client,
            Method::POST,
            &format!("/v1/machines/{machine}/effects/rollback"),
            Some(&json!({ "version": version })),
        )?,
    };
    println!("{}", serde_json::to_string_pretty(&answer)?);
    Ok(())
}
