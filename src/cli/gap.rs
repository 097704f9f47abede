//! `truecut gap ...`: sim-to-real gap diagnosis computed locally by the gap core (no server):
//! `selfcheck` (blind truth plants, confusion matrix), `diagnose` (a motion request body
//! against a machine file) and `csv` (command/actual columns of a CSV trace, e.g. the real
//! traces of the UMich CNC mill set, UMich SMART Lab 2018, not in the repo).

use std::path::PathBuf;

use anyhow::{Context, bail};
use serde_json::{Value, json};

use crate::gap::selfcheck::Generator;
use crate::gap::{GapRequest, MotionOptions, diagnose_motion_request, selfcheck};
use crate::motion::{ServoAxes, servo_axes, stored_definition};

/// Sim-to-real gap diagnosis: which unmodelled effect separates the servo simulation from
/// measured positions, where, and how far the gap shrinks once it is added.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to run.
    #[command(subcommand)]
    pub command: GapCommand,
}

/// `truecut gap` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum GapCommand {
    /// Blind self-check: truth plants with each effect withheld (plus "none" and out-of-library
    /// effects), diagnosed; prints the confusion matrix and the figures (accuracy, `where` on
    /// the literal and the loose reading, median validation shrink, out-of-library answers,
    /// false alarms) with the seed set they come from.
    Selfcheck {
        /// Number of cases (cycling through the generator's kinds: 13 for `wide`, 14 with
        /// `--clock-logs`, 9 for `classic`).
        #[arg(long, default_value_t = 130)]
        cases: usize,
        /// Seed set: `report` (seeds from 1,000,000: only ever used to report figures) or
        /// `tune` (seeds from 1: where thresholds and span ranking are chosen).
        #[arg(long, value_enum, default_value_t = SeedSet::Report)]
        set: SeedSet,
        /// First seed (cases use seed, seed+1, ...); overrides `--set`.
        #[arg(long)]
        seed: Option<u64>,
        /// Truth generator: `wide` (issue 23: contact anywhere, warm validation blocks, cyclic
        /// on any axis, pairs, extremes), `classic` (the fitter's own ranges) or `outside`
        /// (out-of-library plants only, for issue 23's gate).
        #[arg(long, value_enum, default_value_t = GeneratorArg::Wide)]
        generator: GeneratorArg,
        /// Also plant logs on their own clock (delay 2-30 ms, rate 0.5-4x, jitter), put on the
        /// program's grid by the alignment of time-stamped logs (delay and rate estimated).
        #[arg(long)]
        clock_logs: bool,
        /// Override `MotionOptions::min_score` (for tuning on the tuning set).
        #[arg(long)]
        min_score: Option<f64>,
        /// Override `MotionOptions::min_improvement_noise` (for tuning on the tuning set).
        #[arg(long)]
        min_improvement_noise: Option<f64>,
        /// Worker threads.
        #[arg(long, default_value_t = 2)]
        threads: usize,
        /// Print one line per case as well.
        #[arg(long)]
        verbose: bool,
        /// Part-domain cases (random curved surfaces; none, misalignment, thermal, pretravel).
        #[arg(long, default_value_t = 80)]
        part_cases: usize,
    },
    /// Diagnose a motion request body (the JSON of POST .../gap-diagnosis) against a machine
    /// definition file (the JSON of PUT /v1/machines/{id}); prints the answer JSON.
    Diagnose {
        /// Machine-definition JSON file.
        #[arg(long)]
        machine: PathBuf,
        /// Request body JSON file (domain "motion").
        #[arg(long)]
        body: PathBuf,
    },
    /// Diagnose a CSV trace: named command and measured position columns (mm), one row a
    /// sample `--period-s` apart; rows whose `--drop-if` column equals the value are removed.
    Csv {
        /// The CSV file (header row with column names).
        file: PathBuf,
        /// Machine-definition JSON file (its X, Y[, Z] servo models are the simulation).
        #[arg(long)]
        machine: PathBuf,
        /// Sample period, s.
        #[arg(long)]
        period_s: f64,
        /// Command columns, comma-separated (2 or 3), e.g. X1_CommandPosition,Y1_CommandPosition.
        #[arg(long, value_delimiter = ',')]
        commanded: Vec<String>,
        /// Measured columns in the same axis order.
        #[arg(long, value_delimiter = ',')]
        measured: Vec<String>,
        /// Drop rows where COLUMN=VALUE (repeatable), e.g. M1_CURRENT_FEEDRATE=50.
        #[arg(long)]
        drop_if: Vec<String>,
        /// Print the full answer JSON instead of a summary.
        #[arg(long)]
        json: bool,
    },
}

/// Seed sets of the self-check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SeedSet {
    /// Seeds from `selfcheck::TUNE_SEEDS`.
    Tune,
    /// Seeds from `selfcheck::REPORT_SEEDS`.
    Report,
}

/// Truth generators of the self-check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GeneratorArg {
    /// Widened truths (issue 23).
    Wide,
    /// The classic truths.
    Classic,
    /// Out-of-library plants only (issue 23's gate: answered `unexplained`, or named leaving
    /// at least half of the held-out gap).
    Outside,
}

/// Runs `truecut gap ...`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        GapCommand::Selfcheck {
            cases,
            set,
            seed,
            generator,
            clock_logs,
            min_score,
            min_improvement_noise,
            threads,
            verbose,
            part_cases,
        } => {
            let defaults = MotionOptions::default();
            let opts = MotionOptions {
                threads: threads.max(1),
                min_score: min_score.unwrap_or(defaults.min_score),
                min_improvement_noise: min_improvement_noise
                    .unwrap_or(defaults.min_improvement_noise),
                ..defaults
            };
            let seed = seed.unwrap_or(match set {
                SeedSet::Tune => selfcheck::TUNE_SEEDS,
                SeedSet::Report => selfcheck::REPORT_SEEDS,
            });
            let generator = match (generator, clock_logs) {
                (GeneratorArg::Classic, false) => Generator::Classic,
                (GeneratorArg::Outside, false) => Generator::Outside,
                (GeneratorArg::Classic | GeneratorArg::Outside, true) => {
                    bail!("--clock-logs needs --generator wide")
                }
                (GeneratorArg::Wide, false) => Generator::Wide,
                (GeneratorArg::Wide, true) => Generator::WideWithClocks,
            };
            let started = std::time::Instant::now();
            let report = selfcheck::run_with(generator, cases, seed, &opts)?;
            if verbose {
                for c in &report.cases {
                    println!(
                        "{:<15} {:<20} -> {:<20} {:<5} shrink {:>6.1} %  {:?}, noise {:.2} µm  \
                         where {} {}  steps {:?}  left {:.2}  {}",
                        c.category.name(),
                        c.truth,
                        c.verdict.name(),
                        match c.right {
                            None => "-",
                            Some(true) => "ok",
                            Some(false) => "MISS",
                        },
                        100.0 * c.shrink,
                        c.program,
                        c.sigma * 1e3,
                        match (c.where_ok, c.where_literal) {
                            (None, _) => "-",
                            (Some(true), Some(true)) => "ok",
                            (Some(true), _) => "ok loose only",
                            (Some(false), _) => "MISS",
                        },
                        c.where_top,
                        c.steps.iter().map(|e| e.name()).collect::<Vec<_>>(),
                        c.unexplained_share,
                        c.detail
                    );
                }
            }
            print!("{}", report.render());
            if part_cases > 0 {
                print!(
                    "{}",
                    crate::gap::part_selfcheck::run_part(part_cases, seed)?.render()
                );
            }
            println!(
                "elapsed {:.1} s on {threads} thread(s)",
                started.elapsed().as_secs_f64()
            );
            Ok(())
        }
        GapCommand::Diagnose { machine, body } => {
            let m = read_machine(&machine)?;
            let text = std::fs::read_to_string(&body)
                .with_context(|| format!("reading {}", body.display()))?;
            let req: GapRequest = serde_json::from_str(&text)
                .with_context(|| format!("parsing {}", body.display()))?;
            if req.domain != "motion" {
                bail!(
                    "truecut gap diagnose runs the motion domain; part diagnoses need the server's stored surfaces"
                );
            }
            let answer = diagnose_motion_request(&m, &req)?;
            println!("{}", serde_json::to_string_pretty(&answer)?);
            Ok(())
        }
        GapCommand::Csv {
            file,
            machine,
            period_s,
            commanded,
            measured,
            drop_if,
            json,
        } => {
            let m = read_machine(&machine)?;
            let (cmd_rows, meas_rows) = read_csv(&file, &commanded, &measured, &drop_if)?;
            let n = cmd_rows.len();
            let req: GapRequest = serde_json::from_value(json!({
                "domain": "motion", "period_s": period_s,
                "commanded": cmd_rows, "measured": meas_rows,
            }))?;
            let answer = diagnose_motion_request(&m, &req)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&answer)?);
            } else {
                print_summary(&file, n, &answer);
            }
            Ok(())
        }
    }
}

fn read_machine(path: &PathBuf) -> anyhow::Result<ServoAxes> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let def: Value =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    let id = path.display().to_string();
    Ok(servo_axes(&id, &stored_definition(&id, &def)?)?)
}

type Rows = Vec<Vec<f64>>;

fn read_csv(
    file: &PathBuf,
    commanded: &[String],
    measured: &[String],
    drop_if: &[String],
) -> anyhow::Result<(Rows, Rows)> {
    if commanded.len() != measured.len() || !(2..=3).contains(&commanded.len()) {
        bail!("--commanded and --measured need the same 2 or 3 column names");
    }
    let text =
        std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .context("the CSV is empty")?
        .split(',')
        .map(str::trim)
        .collect();
    let col = |name: &str| -> anyhow::Result<usize> {
        header
            .iter()
            .position(|h| *h == name)
            .with_context(|| format!("column '{name}' is not in the header"))
    };
    let ci: Vec<usize> = commanded.iter().map(|c| col(c)).collect::<Result<_, _>>()?;
    let mi: Vec<usize> = measured.iter().map(|c| col(c)).collect::<Result<_, _>>()?;
    let drops: Vec<(usize, String)> = drop_if
        .iter()
        .map(|d| {
            let (c, v) = d.split_once('=').context("--drop-if needs COLUMN=VALUE")?;
            Ok((col(c)?, v.to_string()))
        })
        .collect::<anyhow::Result<_>>()?;
    let (mut cmd, mut meas) = (Vec::new(), Vec::new());
    for (i, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if drops.iter().any(|(c, v)| {
            cells
                .get(*c)
                .is_some_and(|x| x.parse::<f64>().ok() == v.parse::<f64>().ok() || x == v)
        }) {
            continue;
        }
        let get = |k: usize| -> anyhow::Result<f64> {
            cells
                .get(k)
                .and_then(|x| x.parse::<f64>().ok())
                .with_context(|| format!("row {}: column {} is not a number", i + 2, header[k]))
        };
        cmd.push(ci.iter().map(|&k| get(k)).collect::<Result<Vec<_>, _>>()?);
        meas.push(mi.iter().map(|&k| get(k)).collect::<Result<Vec<_>, _>>()?);
    }
    Ok((cmd, meas))
}

fn print_summary(file: &std::path::Path, n: usize, a: &Value) {
    let um = |v: &Value| v.as_f64().unwrap_or(f64::NAN) * 1e3;
    println!(
        "{}: {n} samples, gap rms {:.1} µm (max {:.1} µm), noise estimate {:.1} µm, verdict {}, gap after rms {:.1} µm",
        file.display(),
        um(&a["gap_before"]["rms"]),
        um(&a["gap_before"]["max"]),
        um(&a["noise_mm"]),
        a["verdict"].as_str().unwrap_or("?"),
        um(&a["gap_after"]["rms"]),
    );
    for e in a["effects"].as_array().into_iter().flatten().take(3) {
        println!(
            "  {:<20} score {:>7.3}  {}",
            e["effect"].as_str().unwrap_or("?"),
            e["score"].as_f64().unwrap_or(f64::NAN),
            e["params"]
        );
    }
    for w in a["where"].as_array().into_iter().flatten().take(3) {
        println!(
            "  where {}..{} share {:.2} ({})",
            w["start"],
            w["end"],
            w["share"].as_f64().unwrap_or(0.0),
            w["label"].as_str().unwrap_or("")
        );
    }
}
