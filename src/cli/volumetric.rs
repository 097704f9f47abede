//! `truecut volumetric NODES.csv`: fit a volumetric error map locally (no server needed),
//! print its summary, optionally write the compensation table and the map; or
//! `truecut volumetric --synthetic 7,6,5` to write a synthetic machine's measured grid.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, bail};

use crate::volumetric::{
    self, FitOptions, ModelKind, ShapeFamily, SyntheticMachine, TableSpec, VolumetricData,
};

/// Fit a volumetric error map (trilinear table, Xiang et al. 2019's and Wang, Dai & Hong's 3-8-3
/// network, the ISO 230-1 rigid-body model, or a hybrid; `auto` picks by cross-validation) to
/// measured nodes.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// CSV of measured nodes with header x,y,z,dx,dy,dz (mm). Not needed with --synthetic.
    pub file: Option<PathBuf>,
    /// Model: auto, trilinear, network, kinematic or hybrid.
    #[arg(long, default_value = "auto")]
    pub model: String,
    /// Tool (or reflector) offset from the Z carriage, mm: "x,y,z".
    #[arg(long, default_value = "0,0,0", allow_hyphen_values = true)]
    pub tool_offset: String,
    /// Terms per ISO 230-1 error motion minus one (as a polynomial degree; splines from 4).
    #[arg(long, default_value_t = 5)]
    pub degree: usize,
    /// Controller table limit, points per axis (trilinear model and table export).
    #[arg(long)]
    pub max_points_per_axis: Option<usize>,
    /// Write the compensation table (CSV) here.
    #[arg(long)]
    pub table: Option<PathBuf>,
    /// Table points per axis: "n" or "nx,ny,nz".
    #[arg(long, default_value = "11")]
    pub table_points: String,
    /// Write the fitted map (JSON, as stored by the service) here.
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Print the 21 ISO 230-1 component curves too.
    #[arg(long)]
    pub components: bool,
    /// Instead of fitting, write a synthetic machine's measured grid "nx,ny,nz" as CSV to
    /// stdout (800×500×400 mm travel, 150 mm tool along −Z, 1 µm noise).
    #[arg(long)]
    pub synthetic: Option<String>,
    /// Seed of the synthetic machine.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

fn parse_list<T: std::str::FromStr>(what: &str, v: &str, n: usize) -> anyhow::Result<Vec<T>> {
    let out: Option<Vec<T>> = v.split(',').map(|s| s.trim().parse().ok()).collect();
    match out {
        Some(o) if o.len() == n || (o.len() == 1 && n == 3) => Ok(o),
        _ => bail!("{what} must be {n} comma-separated values, got '{v}'"),
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(grid) = &args.synthetic {
        let g: Vec<usize> = parse_list("--synthetic", grid, 3)?;
        let g = if g.len() == 1 {
            [g[0]; 3]
        } else {
            [g[0], g[1], g[2]]
        };
        if g.iter().any(|&n| !(2..=200).contains(&n)) {
            bail!("--synthetic needs 2..200 points per axis, got {grid}");
        }
        let m = SyntheticMachine::new(args.seed, ShapeFamily::TrendAndWaviness);
        let d = m.measure_grid(g, args.seed + 1000);
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        writeln!(out, "x,y,z,dx,dy,dz")?;
        for (p, e) in d.nodes.iter().zip(&d.errors) {
            writeln!(
                out,
                "{},{},{},{:.6},{:.6},{:.6}",
                p[0], p[1], p[2], e[0], e[1], e[2]
            )?;
        }
        return Ok(());
    }
    let Some(file) = &args.file else {
        bail!("give a CSV file of nodes (x,y,z,dx,dy,dz) or --synthetic nx,ny,nz");
    };
    let text =
        std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
    let data = VolumetricData::from_csv(&text)?;
    let t: Vec<f64> = parse_list("--tool-offset", &args.tool_offset, 3)?;
    if t.len() != 3 {
        bail!("--tool-offset must be x,y,z in mm");
    }
    let options = FitOptions {
        model: ModelKind::parse(&args.model)?,
        tool_offset_mm: [t[0], t[1], t[2]],
        degree: args.degree,
        max_points_per_axis: args.max_points_per_axis,
        ..FitOptions::default()
    };
    let map = volumetric::fit(&data, &options)?;
    let mut summary = serde_json::json!({
        "model": map.model.kind().name(),
        "parameter_count": map.model.parameter_count(),
        "n_nodes": map.n_nodes,
        "cv_scheme": map.cv_scheme,
        "scores": map.scores,
        "fit_rms_mm": map.fit_rms_mm,
        "bounds": map.bounds,
    });
    if args.components {
        summary["components"] = serde_json::to_value(
            map.components
                .as_ref()
                .map(|k| volumetric::component_curves(k, 21)),
        )?;
    }
    if let Some(path) = &args.table {
        let p: Vec<usize> = parse_list("--table-points", &args.table_points, 3)?;
        let p = if p.len() == 1 {
            [p[0]; 3]
        } else {
            [p[0], p[1], p[2]]
        };
        let mut spec = TableSpec::over(&map, p);
        spec.max_points_per_axis = args.max_points_per_axis;
        let csv = volumetric::compensation_table_csv(&map, &spec)?;
        std::fs::write(path, csv).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("compensation table written to {}", path.display());
    }
    if let Some(path) = &args.output {
        std::fs::write(path, map.to_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
        eprintln!("map written to {}", path.display());
    }
    // the summary last, so that files are written even when stdout is closed early (| head)
    let text = serde_json::to_string_pretty(&summary)?;
    match writeln!(std::io::stdout().lock(), "{text}") {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}
