//! Volumetric error maps on synthetic machines with known ISO 230-1 errors: off-grid
//! RMS error of each model against the truth, stored numbers, ratio to trilinear (the
//! controller's table), on a fine 7×6×5 and a coarse 4×4×3 grid.
//!
//! Run: `cargo bench --bench volumetric` (add `-- quick` for 2 seeds).

use std::time::Instant;
use truecut::volumetric::{FitOptions, ModelKind, ShapeFamily, SyntheticMachine, fit};

const KINDS: [ModelKind; 5] = [
    ModelKind::Trilinear,
    ModelKind::Network,
    ModelKind::Kinematic,
    ModelKind::Hybrid,
    ModelKind::Auto,
];

struct Row {
    rms_um: Vec<f64>,
    params: Vec<usize>,
    secs: Vec<f64>,
    chosen: Vec<ModelKind>,
}

fn run(family: ShapeFamily, sag_mm: f64, grid: [usize; 3], seeds: &[u64]) -> Vec<Row> {
    let mut rows: Vec<Row> = KINDS
        .iter()
        .map(|_| Row {
            rms_um: vec![],
            params: vec![],
            secs: vec![],
            chosen: vec![],
        })
        .collect();
    for &seed in seeds {
        let mut m = SyntheticMachine::new(seed, family);
        m.sag_mm = sag_mm;
        let data = m.measure_grid(grid, seed + 1000);
        let pts = m.random_points(5000, seed + 2000);
        let truth: Vec<[f64; 3]> = pts.iter().map(|&p| m.error(p)).collect();
        for (r, &kind) in rows.iter_mut().zip(&KINDS) {
            let opts = FitOptions {
                model: kind,
                tool_offset_mm: m.tool_offset_mm,
                ..FitOptions::default()
            };
            let t0 = Instant::now();
            let map = fit(&data, &opts).expect("fit");
            r.secs.push(t0.elapsed().as_secs_f64());
            let pred = map.predict(&pts).expect("predict").errors;
            let se: f64 = pred
                .iter()
                .zip(&truth)
                .map(|(p, t)| (0..3).map(|j| (p[j] - t[j]).powi(2)).sum::<f64>())
                .sum();
            r.rms_um.push((se / pts.len() as f64).sqrt() * 1e3);
            r.params.push(map.model.parameter_count());
            r.chosen.push(map.model.kind());
        }
    }
    rows
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn table(title: &str, family: ShapeFamily, sag_mm: f64, seeds: &[u64]) {
    println!("\n### {title} ({} seeds: {:?})\n", seeds.len(), seeds);
    println!(
        "| grid | model | off-grid RMS µm (mean) | worst seed µm | params (mean) | RMS ratio to trilinear (mean, worst) | fit time s (mean) | time ratio to trilinear |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for grid in [[7, 6, 5], [4, 4, 3]] {
        let rows = run(family, sag_mm, grid, seeds);
        let tri = &rows[0];
        for (r, kind) in rows.iter().zip(&KINDS) {
            let ratios: Vec<f64> = r
                .rms_um
                .iter()
                .zip(&tri.rms_um)
                .map(|(a, b)| a / b)
                .collect();
            let name = if *kind == ModelKind::Auto {
                let mut c: Vec<&str> = r.chosen.iter().map(|k| k.name()).collect();
                c.dedup();
                format!("auto → {}", c.join("/"))
            } else {
                kind.name().to_string()
            };
            println!(
                "| {}×{}×{} | {} | {:.2} | {:.2} | {:.0} | {:.2}, {:.2} | {:.3} | {:.1} |",
                grid[0],
                grid[1],
                grid[2],
                name,
                mean(&r.rms_um),
                r.rms_um.iter().cloned().fold(0.0, f64::max),
                mean(&r.params.iter().map(|&p| p as f64).collect::<Vec<_>>()),
                mean(&ratios),
                ratios.iter().cloned().fold(0.0, f64::max),
                mean(&r.secs),
                mean(&r.secs) / mean(&tri.secs),
            );
        }
    }
}

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    let seeds: Vec<u64> = if quick { vec![1, 2] } else { (1..=6).collect() };
    table(
        "Rigid machine, trend + waviness error motions (default family)",
        ShapeFamily::TrendAndWaviness,
        0.0,
        &seeds,
    );
    table(
        "Rigid machine, long-wave error motions (stress case)",
        ShapeFamily::LongWave,
        0.0,
        &seeds,
    );
    table(
        "Trend + waviness plus an 8 µm non-rigid sag",
        ShapeFamily::TrendAndWaviness,
        8e-3,
        &seeds,
    );
}
