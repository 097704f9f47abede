//! `truecut jobs ...`: background jobs of a running service: `list`, `get ID [--wait]`,
//! `cancel ID`, and `submit PATH BODY.json [--wait]` (POST a body to a route that may answer
//! `202 {"job": id}`, then follow the job). Following shows a progress bar on a terminal and
//! one line per change of state when piped; a job that ends failed or cancelled exits 5.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use reqwest::Method;
use serde_json::Value;

use super::client::{Client, ClientError, ServerArgs, interactive};

/// Background jobs of a running service.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  truecut jobs list --state running\n  \
    truecut jobs submit /v1/machines/m1/surfaces/s1/step-error-model train.json --wait > result.json\n  \
    truecut jobs get 0193c1e2-... --wait")]
pub struct Args {
    /// Where the service is.
    #[command(flatten)]
    pub server: ServerArgs,
    /// What to do.
    #[command(subcommand)]
    pub command: JobsCommand,
}

/// `truecut jobs` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum JobsCommand {
    /// List jobs, newest first (JSON on stdout).
    #[command(after_help = "Example:\n  truecut jobs list --state failed --limit 10")]
    List {
        /// Only jobs in this state (queued, running, done, failed, cancelled).
        #[arg(long)]
        state: Option<String>,
        /// At most this many.
        #[arg(long)]
        limit: Option<usize>,
        /// The page after this cursor (the `next` of the previous answer).
        #[arg(long)]
        cursor: Option<String>,
        /// Also list each job's result (at most 100 a page).
        #[arg(long)]
        result: bool,
    },
    /// Show a job (JSON on stdout); with --wait, follow it to its end and print its result.
    #[command(
        after_help = "Example:\n  truecut jobs get 0193c1e2-7f00-7abc-8def-0123456789ab --wait"
    )]
    Get {
        /// Job id.
        id: String,
        /// Follow the job until it ends.
        #[arg(long)]
        wait: bool,
    },
    /// Cancel a queued or running job.
    #[command(after_help = "Example:\n  truecut jobs cancel 0193c1e2-7f00-7abc-8def-0123456789ab")]
    Cancel {
        /// Job id.
        id: String,
    },
    /// POST a JSON body to a route; a 202 job is followed with --wait (its result on stdout),
    /// any other answer is printed as is.
    #[command(
        after_help = "Example:\n  truecut jobs submit /v1/machines/demo/surfaces/saddle/step-error-model body.json --wait"
    )]
    Submit {
        /// The route, e.g. /v1/machines/m1/surfaces/s1/step-error-model.
        path: String,
        /// The JSON body file (`-` for stdin).
        body: PathBuf,
        /// Follow the job until it ends.
        #[arg(long)]
        wait: bool,
    },
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let client = Client::new(&args.server)?;
    let answer = match args.command {
        JobsCommand::List {
            state,
            limit,
            cursor,
            result,
        } => {
            let mut q: Vec<(&str, String)> = Vec::new();
            if let Some(s) = state {
                q.push(("state", s));
            }
            if let Some(l) = limit {
                q.push(("limit", l.to_string()));
            }
            if let Some(c) = cursor {
                q.push(("cursor", c));
            }
            if result {
                q.push(("result", "true".to_string()));
            }
            let rb = client.request(Method::GET, "/v1/jobs").query(&q);
            client
                .runtime
                .block_on(async { anyhow::Ok(client.send(rb).await?.json::<Value>().await?) })?
        }
        JobsCommand::Get { id, wait } => {
            if wait {
                follow(&client, &id)?
            } else {
                get(&client, &id)?
            }
        }
        JobsCommand::Cancel { id } => {
            let rb = client.request(Method::DELETE, &format!("/v1/jobs/{id}"));
            client
                .runtime
                .block_on(async { anyhow::Ok(client.send(rb).await?.json::<Value>().await?) })?
        }
        JobsCommand::Submit { path, body, wait } => {
            let text = if body.as_os_str() == "-" {
                std::io::read_to_string(std::io::stdin())
                    .context("cannot read the body from stdin")?
            } else {
                std::fs::read_to_string(&body)
                    .with_context(|| format!("cannot read {}", body.display()))?
            };
            let json: Value = serde_json::from_str(&text)
                .with_context(|| format!("{} is not JSON", body.display()))?;
            let rb = client.request(Method::POST, &path).json(&json);
            let (status, answer) = client.runtime.block_on(async {
                let resp = client.send(rb).await?;
                let status = resp.status().as_u16();
                anyhow::Ok((status, resp.json::<Value>().await?))
            })?;
            match answer.get("job").and_then(Value::as_str) {
                Some(id) if status == 202 => {
                    eprintln!("job {id} accepted");
                    if wait {
                        follow(&client, id)?
                    } else {
                        answer.clone()
                    }
                }
                _ => answer,
            }
        }
    };
    println!("{}", serde_json::to_string_pretty(&answer)?);
    Ok(())
}

fn get(client: &Client, id: &str) -> anyhow::Result<Value> {
    let rb = client.request(Method::GET, &format!("/v1/jobs/{id}"));
    client
        .runtime
        .block_on(async { anyhow::Ok(client.send(rb).await?.json::<Value>().await?) })
}

/// Polls the job every 200 ms until it ends; its `result` on success, exit 5 otherwise.
pub fn follow(client: &Client, id: &str) -> anyhow::Result<Value> {
    let tty = interactive();
    let bar = if tty {
        let bar = ProgressBar::new(1000);
        bar.set_style(ProgressStyle::with_template(
            "job {msg} [{bar:30}] {percent}% {elapsed}",
        )?);
        bar.set_message(id.to_string());
        bar
    } else {
        ProgressBar::hidden()
    };
    let mut last_state = String::new();
    let mut last_decile = -1_i64;
    loop {
        let status = get(client, id)?;
        let state = status["state"].as_str().unwrap_or("unknown").to_string();
        let progress = status["progress"].as_f64().unwrap_or(0.0).clamp(0.0, 1.0);
        bar.set_position((progress * 1000.0) as u64);
        let decile = (progress * 10.0).floor() as i64;
        if !tty && (state != last_state || decile != last_decile) {
            eprintln!("job {id}: {state} {:.0} %", progress * 100.0);
        }
        (last_state, last_decile) = (state.clone(), decile);
        match state.as_str() {
            "done" => {
                bar.finish_and_clear();
                return Ok(status.get("result").cloned().unwrap_or(Value::Null));
            }
            "failed" | "cancelled" => {
                bar.abandon();
                return Err(ClientError::JobFailed {
                    id: id.to_string(),
                    state,
                    error: status["error"]
                        .as_str()
                        .unwrap_or("no reason given")
                        .to_string(),
                }
                .into());
            }
            _ => std::thread::sleep(Duration::from_millis(200)),
        }
    }
}
