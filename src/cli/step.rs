//! `truecut step ...`: step error of ball-end finishing (Zhang et al. 2023), computed locally by
//! the geometry and nn cores (no server needed). Files use the JSON bodies of the HTTP routes.

use std::path::PathBuf;

use anyhow::{Context, bail};
use serde::Deserialize;

use crate::geometry::{
    HeightSurface, PathPlan, StepErrorSegment, height_surface_segments, step_errors,
};
use crate::nn::{Init, Regressor, TrainConfig};
use crate::step_error::{TrainJob, model_features, predict_um};

/// Step error of ball-end toolpaths: exact geometry, sample generation, the network.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub command: StepCommand,
}

/// The `step` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum StepCommand {
    /// Exact step errors (mm) of the segments in FILE ({"tool_radius": mm, "segments": [...]},
    /// the body of POST /v1/step-error); prints {"step_errors": [...]}.
    Exact {
        /// JSON file.
        file: PathBuf,
    },
    /// Labelled samples: iso-parametric paths over an analytic surface (the study's surface
    /// 1-3 with --reference, or a height-surface JSON file with --surface).
    Samples {
        /// The Python study's surface 1, 2 or 3.
        #[arg(long, conflicts_with = "surface")]
        reference: Option<u32>,
        /// Height surface JSON ({"lx", "ly", "scale", "offset", "terms": [{"sc": [..]}, {"gauss": [..]}]}).
        #[arg(long)]
        surface: Option<PathBuf>,
        /// Ball radius, mm.
        #[arg(long, default_value_t = 5.0)]
        tool_radius: f64,
        /// Number of paths (default 200, the study's).
        #[arg(long, default_value_t = 200)]
        lines: usize,
        /// CL points per path (default 100, the study's).
        #[arg(long, default_value_t = 100)]
        points: usize,
        /// CC points per segment, ends included.
        #[arg(long, default_value_t = 20)]
        cc_points: usize,
        /// Output file (default: stdout).
        #[arg(long)]
        output: Option<PathBuf>,
    },
    /// Train the network on a samples file (from `step samples` or the samples route) and write
    /// the model file; with --base, fine-tune that model instead.
    Train {
        /// Samples JSON ({"tool_radius", "segments": [...]}).
        file: PathBuf,
        /// Model file to write.
        #[arg(long)]
        output: PathBuf,
        /// Model file to fine-tune.
        #[arg(long)]
        base: Option<PathBuf>,
        /// Maximum epochs (default 300; 100 when fine-tuning).
        #[arg(long)]
        epochs: Option<usize>,
        /// Use Zhang et al. 2023's settings (N(0,1), SGD 1e-5 momentum 0.8, dropout 0.5).
        #[arg(long)]
        paper: bool,
        /// Held-out fraction for the reported test errors.
        #[arg(long, default_value_t = 0.3)]
        test_fraction: f64,
    },
    /// The transfer study (issue 12): generated surfaces (ridges, ripples, steps, bumps,
    /// saddles, waves, mixtures; heights 20-60 mm, turned, R 3-8 mm, m 11-31, varied steps),
    /// a network trained on each of the first N, every other surface predicted zero-shot, the
    /// worst surfaces fine-tuned on 15 %; prints per-surface figures and the worst beside the
    /// goals.
    Transfer {
        /// Number of generated surfaces.
        #[arg(long, default_value_t = 24)]
        surfaces: usize,
        /// Train a network on each of the first N surfaces.
        #[arg(long, default_value_t = 24)]
        train_on: usize,
        /// Most segments taken of each surface.
        #[arg(long, default_value_t = 6000)]
        budget: usize,
        /// Also run the previous default (local-frame coordinates, two outputs) for comparison.
        #[arg(long)]
        coordinates: bool,
        /// Print the whole report as JSON at the end.
        #[arg(long)]
        json: bool,
    },
    /// Predict step errors (mm) of the segments in FILE with a model file.
    Predict {
        /// JSON file ({"tool_radius"?: mm, "segments": [...]}).
        file: PathBuf,
        /// Model file (from `step train`).
        #[arg(long)]
        model: PathBuf,
    },
}

#[derive(Deserialize)]
struct SegmentsFile {
    #[serde(default)]
    tool_radius: Option<f64>,
    segments: Vec<StepErrorSegment>,
}

fn read_segments(file: &PathBuf) -> anyhow::Result<SegmentsFile> {
    let text = std::fs::read(file).with_context(|| format!("cannot read {}", file.display()))?;
    serde_json::from_slice(&text).with_context(|| {
        format!(
            "{} is not {{\"tool_radius\", \"segments\": [...]}}",
            file.display()
        )
    })
}

/// Runs `truecut step ...`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        StepCommand::Exact { file } => {
            let f = read_segments(&file)?;
            let r = f.tool_radius.context("tool_radius (mm) is missing")?;
            let e = step_errors(r, &f.segments, 0)?;
            let errs: Vec<f64> = e.iter().map(|e| e.error_mm).collect();
            let infl: Vec<usize> = e
                .iter()
                .enumerate()
                .filter(|(_, e)| e.inflection)
                .map(|(i, _)| i)
                .collect();
            println!(
                "{}",
                serde_json::json!({"step_errors": errs, "inflections": infl, "unit": "mm"})
            );
        }
        StepCommand::Samples {
            reference,
            surface,
            tool_radius,
            lines,
            points,
            cc_points,
            output,
        } => {
            let s = match (reference, surface) {
                (Some(id), _) => {
                    HeightSurface::reference(id).context("--reference must be 1, 2 or 3")?
                }
                (None, Some(p)) => serde_json::from_slice(&std::fs::read(&p)?)
                    .context("bad height-surface JSON")?,
                (None, None) => bail!("give --reference N or --surface FILE"),
            };
            let plan = PathPlan {
                tool_radius_mm: tool_radius,
                lines: Some(lines),
                points_per_line: Some(points),
                cc_points,
                step_over_mm: None,
                cl_spacing_mm: None,
            };
            let segs = height_surface_segments(&s, &plan)?;
            let e = step_errors(tool_radius, &segs, 0)?;
            let body = serde_json::json!({
                "tool_radius": tool_radius,
                "segments": segs,
                "step_errors": e.iter().map(|e| e.error_mm).collect::<Vec<_>>(),
                "unit": "mm",
            });
            match output {
                Some(p) => std::fs::write(&p, serde_json::to_vec(&body)?)?,
                None => println!("{body}"),
            }
            eprintln!(
                "{} segments, max step error {:.3} um",
                e.len(),
                e.iter().map(|e| e.error_mm).fold(0.0, f64::max) * 1e3
            );
        }
        StepCommand::Train {
            file,
            output,
            base,
            epochs,
            paper,
            test_fraction,
        } => {
            let f = read_segments(&file)?;
            let r = f.tool_radius.context("tool_radius (mm) is missing")?;
            let mut job = TrainJob::new(r);
            job.test_fraction = test_fraction;
            if paper {
                job.cfg = TrainConfig::paper();
                job.init = Init::StandardNormal;
            }
            if let Some(b) = base {
                let bytes =
                    std::fs::read(&b).with_context(|| format!("cannot read {}", b.display()))?;
                job.base = Some(Regressor::from_bytes(&bytes)?);
                job.base_name = Some(serde_json::json!(b.display().to_string()));
                job.cfg.epochs = 100;
                job.cfg.patience = Some(20);
            }
            if let Some(e) = epochs {
                job.cfg.epochs = e;
            }
            let (reg, report) = job.run(&f.segments, &|p| {
                eprint!("\rtraining {:>3.0} %", p * 100.0);
                true
            })?;
            eprintln!();
            std::fs::write(&output, reg.to_bytes())
                .with_context(|| format!("cannot write {}", output.display()))?;
            println!("{}", serde_json::to_string_pretty(&report)?);
        }
        StepCommand::Predict { file, model } => {
            let f = read_segments(&file)?;
            let reg = Regressor::from_bytes(
                &std::fs::read(&model)
                    .with_context(|| format!("cannot read {}", model.display()))?,
            )?;
            let (features, r_model) = model_features(&reg)?;
            let r = f.tool_radius.unwrap_or(r_model);
            let p = predict_um(
                &reg,
                &features,
                r,
                f.segments.iter().map(|s| (s.cl, &s.cc[..])),
            )?;
            let e: Vec<f64> = p.um.into_iter().map(|v| v / 1000.0).collect();
            println!("{}", serde_json::json!({"step_errors": e, "unit": "mm"}));
        }
        StepCommand::Transfer {
            surfaces,
            train_on,
            budget,
            coordinates,
            json,
        } => super::step_transfer::run(surfaces, train_on, budget, coordinates, json)?,
    }
    Ok(())
}
