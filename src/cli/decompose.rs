//! `truecut decompose FILE`: split a machining error (CSV or JSON) into systematic and random
//! parts offline, with the same cores as the service.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, bail};

use crate::signal::{DecomposeParams, Method, Order, decompose};

/// Decompose a machining error into systematic and random parts (Chen et al. 2024: VMD, EMD,
/// wavelet, coarse-to-fine). Prints CSV `signal,systematic,random` (mm) or the service's JSON.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input: CSV (one number per line, or a header naming a `deviation`/`signal` column) or
    /// JSON (an array, or an object with `signal` or `deviations`).
    pub file: PathBuf,
    /// Method: coarse_to_fine (default), vmd, emd or wavelet.
    #[arg(long, default_value = "coarse_to_fine")]
    pub method: String,
    /// Grid shape "nu,nv" when the samples are a probe grid (point k = iv*nu + iu).
    #[arg(long)]
    pub grid: Option<String>,
    /// How a grid is read: 2d (default), serpentine or row_major.
    #[arg(long, default_value = "2d")]
    pub order: String,
    /// Further parameters as JSON, e.g. '{"vmd": {"alpha": 1000}, "refine": false}'.
    #[arg(long)]
    pub params: Option<String>,
    /// Output format: csv (default) or json (the service's response, with stage details).
    #[arg(long, default_value = "csv")]
    pub format: String,
    /// Write here instead of stdout.
    #[arg(long, short)]
    pub output: Option<PathBuf>,
}

/// Reads the samples from CSV or JSON text.
pub fn read_signal(text: &str) -> anyhow::Result<Vec<f64>> {
    let trimmed = text.trim_start();
    if trimmed.starts_with('[') || trimmed.starts_with('{') {
        let v: serde_json::Value =
            serde_json::from_str(trimmed).context("input is not valid JSON")?;
        let arr = match &v {
            serde_json::Value::Array(a) => a,
            serde_json::Value::Object(o) => o
                .get("signal")
                .or_else(|| o.get("deviations"))
                .and_then(|s| s.as_array())
                .context("JSON input needs a \"signal\" or \"deviations\" array")?,
            _ => bail!("JSON input must be an array of numbers"),
        };
        return arr
            .iter()
            .enumerate()
            .map(|(i, x)| {
                x.as_f64()
                    .with_context(|| format!("signal[{i}] is not a number"))
            })
            .collect();
    }
    let mut lines = text.lines().filter(|l| !l.trim().is_empty()).peekable();
    let first = lines.peek().context("the input file is empty")?.to_string();
    let cells: Vec<&str> = first.split(',').map(str::trim).collect();
    let (col, skip) = if cells.iter().all(|c| c.parse::<f64>().is_ok()) {
        (cells.len() - 1, 0)
    } else {
        let col = cells
            .iter()
            .position(|c| {
                ["deviation", "signal", "error"].contains(&c.to_ascii_lowercase().as_str())
            })
            .unwrap_or(cells.len() - 1);
        (col, 1)
    };
    lines
        .skip(skip)
        .enumerate()
        .map(|(i, l)| {
            let cell = l.split(',').nth(col).map(str::trim).unwrap_or("");
            cell.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .with_context(|| format!("data line {}: '{cell}' is not a finite number", i + 1))
        })
        .collect()
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(&args.file)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    let x = read_signal(&text)?;
    let method: Method = serde_json::from_value(serde_json::Value::String(args.method.clone()))
        .with_context(|| {
            format!(
                "unknown method '{}': use coarse_to_fine, vmd, emd or wavelet",
                args.method
            )
        })?;
    let mut params: DecomposeParams = match &args.params {
        Some(p) => serde_json::from_str(p).context("--params is not a valid parameter object")?,
        None => DecomposeParams::default(),
    };
    if let Some(g) = &args.grid {
        let v: Vec<usize> = g.split(',').filter_map(|s| s.trim().parse().ok()).collect();
        let [nu, nv] = v[..] else {
            bail!("--grid must be \"nu,nv\", got '{g}'");
        };
        params.nu = Some(nu);
        params.nv = Some(nv);
        params.order =
            serde_json::from_value::<Order>(serde_json::Value::String(args.order.clone()))
                .with_context(|| {
                    format!(
                        "unknown order '{}': use 2d, serpentine or row_major",
                        args.order
                    )
                })?;
    }
    let d = decompose(&x, method, &params)?;
    let mut out: Box<dyn Write> = match &args.output {
        Some(p) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("cannot write {}", p.display()))?,
        )),
        None => Box::new(std::io::BufWriter::new(std::io::stdout().lock())),
    };
    match args.format.as_str() {
        "json" => serde_json::to_writer(&mut out, &d)?,
        "csv" => {
            writeln!(out, "signal,systematic,random")?;
            for ((x, s), r) in x.iter().zip(&d.systematic).zip(&d.random) {
                writeln!(out, "{x},{s},{r}")?;
            }
        }
        other => bail!("unknown --format '{other}': use csv or json"),
    }
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests;
