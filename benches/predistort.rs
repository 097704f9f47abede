//! Contour-error pre-distortion speed (issue 14): machine time compensated per wall-clock
//! second for a circle program and a free-form G01 program on the demo machine's cascade, one
//! core. Baseline measured in the same run: one plain `predict_program` of the original (what
//! the contour-error route does), so the ratio reads "the compensation costs N predictions".
//! Goal: ≥ 100× real time for the whole compensation.
//!
//! Run: `cargo bench --bench predistort`

use std::time::Instant;

use serde_json::json;
use truecut::cam::{DEFAULT_BAND_MM, DEFAULT_MAX_DURATION_RATIO, PredistortOptions, predistort};
use truecut::motion::{Machine, Program, gcode, predict_program};

fn machine() -> Machine {
    let ax = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}}))
        .expect("bench machine")
}

/// Ten full circles of R 25 mm at F 3000 with tangent lead-in and lead-out (≈ 34 s).
fn circles() -> String {
    let mut p = String::from("G90 G17 G94\nG1 X0 Y15 F3000\n");
    for _ in 0..10 {
        p += "G3 X0 Y15 I-25 J0\n";
    }
    p + "G1 Y30\n"
}

/// A CAM-like G01 polyline (0.25 mm chords) along y = 6 sin(2πx/60) + 1.5 sin(2πx/23),
/// x in 0..1200 mm at F 2500 (≈ 30 s), with a tangent lead-in.
fn free_form() -> String {
    let tau = std::f64::consts::TAU;
    let f = |x: f64| 6.0 * (tau * x / 60.0).sin() + 1.5 * (tau * x / 23.0).sin();
    let slope = 6.0 * tau / 60.0 + 1.5 * tau / 23.0;
    let n = (1.0 + slope * slope).sqrt();
    let (x0, y0) = (10.0 / n, 10.0 * slope / n);
    let mut p = format!("G90 G17 G94\nG1 X{x0:.4} Y{y0:.4} F2500\n");
    for k in 1..=4800 {
        let x = k as f64 * 0.25;
        p += &format!("G1 X{:.4} Y{:.4}\n", x0 + x, y0 + f(x));
    }
    p
}

fn run(name: &str, m: &Machine, prog: &Program) {
    let opts = PredistortOptions {
        period_s: 1e-3,
        max_iterations: 30,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
        band_mm: DEFAULT_BAND_MM,
    };
    // Warm-up, then the best of three of each.
    let _ = predistort(m, prog, &opts).expect("predistort");
    let mut base = f64::INFINITY;
    let mut duration_s = 0.0;
    for _ in 0..3 {
        let t = Instant::now();
        let p = predict_program(m, prog, 1e-3, 10_000_000).expect("predict");
        base = base.min(t.elapsed().as_secs_f64());
        duration_s = p.commanded.t.len() as f64 * 1e-3;
    }
    let mut wall = f64::INFINITY;
    let mut out = None;
    for _ in 0..3 {
        let t = Instant::now();
        let r = predistort(m, prog, &opts).expect("predistort");
        wall = wall.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    let out = out.expect("ran");
    println!(
        "{name}: {duration_s:.1} s of machine time, {} iterations, {} lines rewritten; predistort {:.3} s wall \
         = {:.0}x real time (goal >= 100x); baseline predict_program {:.3} s ({:.0}x real time); \
         ratio predistort/predict {:.1}; RMS {:.2} -> {:.2} um ({:.3}x), max {:.2} -> {:.2} um ({:.3}x)",
        out.iterations,
        out.lines.len(),
        wall,
        duration_s / wall,
        base,
        duration_s / base,
        wall / base,
        out.original.rms_mm * 1e3,
        out.compensated.rms_mm * 1e3,
        out.compensated.rms_mm / out.original.rms_mm,
        out.original.max_mm * 1e3,
        out.compensated.max_mm * 1e3,
        out.compensated.max_mm / out.original.max_mm,
    );
}

fn main() {
    let m = machine();
    run(
        "circles R25 F3000 x10",
        &m,
        &gcode::parse(&circles()).expect("circles"),
    );
    run(
        "free-form G01 F2500",
        &m,
        &gcode::parse(&free_form()).expect("free-form"),
    );
}
