//! Volumetric compensation speed of a long program (`cam::compensate_program`): a 20,000-block
//! finishing program (G1 lines and G2/G3 arcs) against a kinematic map fitted on a synthetic
//! machine, compared in the same run with (a) the plain parse of the same program (the
//! reader alone) and (b) the map's own cost per point (`VolumetricMap::predict` of as many
//! points as the compensation evaluated would need at 5 per block). Prints blocks/s and
//! ratios; CPU time is wall clock of one thread (the machine may be shared).
//!
//! Run: `cargo bench --bench compensated_program`

use std::time::Instant;

use truecut::cam::compensate_program;
use truecut::motion::{ReadOptions, parse_with};
use truecut::volumetric::{FitOptions, ModelKind, ShapeFamily, SyntheticMachine, fit};

/// A finishing program of `n` motion blocks: rows of G1 lines joined by 180° arcs, in a
/// 500 × 300 mm field at Z 250 (machine frame inside the map's box).
fn program(n: usize) -> String {
    let mut p =
        String::from("%\nO1000 (BENCH)\nG90 G17 G21 G94\nG0 X100. Y100. Z260.\nG1 Z250. F1000.\n");
    let mut blocks = 0;
    let mut y = 100.0;
    let mut right = true;
    while blocks < n {
        // A row of 20 mm G1 steps along X.
        for k in 1..=24 {
            let x = if right {
                100.0 + 20.0 * k as f64
            } else {
                580.0 - 20.0 * k as f64
            };
            p += &format!("N{} G1 X{x:.3} Y{y:.3} F2000.\n", blocks + 1);
            blocks += 1;
        }
        let x = if right { 580.0 } else { 100.0 };
        let g = if right { "G3" } else { "G2" };
        p += &format!("N{} {g} X{x:.3} Y{:.3} I0. J0.5\n", blocks + 1, y + 1.0);
        blocks += 1;
        y += 1.0;
        if y > 400.0 {
            y = 100.0;
        }
        right = !right;
    }
    p += "G0 Z300.\nM30\n%\n";
    p
}

fn main() {
    let m = SyntheticMachine::new(8, ShapeFamily::TrendAndWaviness);
    let data = m.measure_grid([7, 6, 5], 3);
    let opts = FitOptions {
        model: ModelKind::Kinematic,
        tool_offset_mm: m.tool_offset_mm,
        ..FitOptions::default()
    };
    let map = fit(&data, &opts).expect("map fit");
    let n = 20_000;
    let text = program(n);
    let read = ReadOptions::default();
    let reps = 3;

    let t = Instant::now();
    let mut parsed = 0;
    for _ in 0..reps {
        parsed += parse_with(&text, &read).expect("parse").0.blocks.len();
    }
    let parse_s = t.elapsed().as_secs_f64() / reps as f64;

    let points: Vec<[f64; 3]> = (0..5 * n)
        .map(|i| [100.0 + (i % 480) as f64, 100.0 + (i % 300) as f64, 250.0])
        .collect();
    let t = Instant::now();
    for _ in 0..reps {
        std::hint::black_box(map.predict(&points).expect("predict"));
    }
    let predict_s = t.elapsed().as_secs_f64() / reps as f64;

    for tol in [0.001, 0.0002] {
        let t = Instant::now();
        let mut out = None;
        for _ in 0..reps {
            out = Some(compensate_program(&text, &read, &map, tol).expect("compensate"));
        }
        let comp_s = t.elapsed().as_secs_f64() / reps as f64;
        let out = out.expect("ran");
        println!(
            "compensate {n} blocks, tolerance {tol} mm: {:.1} ms = {:.0} blocks/s; {} blocks out, \
             max shift {:.1} µm",
            comp_s * 1e3,
            n as f64 / comp_s,
            out.blocks,
            out.max_shift_mm * 1e3
        );
        println!(
            "  ratio to the plain parse ({:.1} ms, {} blocks): {:.1}x; to predict of 5 points per \
             block ({:.1} ms): {:.2}x",
            parse_s * 1e3,
            parsed / reps,
            comp_s / parse_s,
            predict_s * 1e3,
            comp_s / predict_s
        );
    }
}
