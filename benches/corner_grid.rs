//! Issue 24 item 4 over its whole range: contour pre-distortion of five corner programs
//! (the 2 mm staircase, the issue's circle + 140° + 90° contour, line–half circle–line, the
//! 140° turn + 90° corner, the 10 mm square) at F 1000, 2000 and 3000 mm/min on axes of
//! kv 30, 45 and 60 (the demo cascade otherwise), default `max_duration_ratio` 1.15.
//! Prints, per case, the distance-weighted RMS, max and duration ratios against the
//! uncompensated program (gates ≤ 0.3×, ≤ 0.5×, ≤ 1.15×; no gouge beyond the original's),
//! whether all gates are met, and the wall time against the baseline measured in the same
//! run: one plain `predict_program` of the original (so "N predictions" is what the
//! compensation costs).
//!
//! Run: `cargo bench --bench corner_grid` (about 2 minutes on one core);
//! `cargo bench --bench corner_grid -- stair` runs one program.

use std::time::Instant;

use serde_json::json;
use truecut::cam::{DEFAULT_MAX_DURATION_RATIO, PredistortOptions, predistort};
use truecut::motion::{Machine, gcode, predict_program};

fn machine(kv: f64) -> Machine {
    let ax = json!({"kv": kv, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}}))
        .expect("bench machine")
}

/// A point `len` mm from `(x, y)` in direction `deg` (degrees from +X), 4 decimals.
fn step(x: f64, y: f64, deg: f64, len: f64) -> (f64, f64) {
    let r = deg.to_radians();
    (
        ((x + len * r.cos()) * 1e4).round() / 1e4,
        ((y + len * r.sin()) * 1e4).round() / 1e4,
    )
}

/// 2 mm steps: ten 90° corners turning left and right.
fn stair(feed: f64) -> String {
    let mut p = format!("G90 G17 G94\nG1 X2 F{feed}\n");
    for k in 1..=5 {
        p += &format!("G1 Y{}\nG1 X{}\n", 2 * k, 2 * k + 2);
    }
    p
}

/// A full circle R 10 entered and left tangentially, then a 140° and a 90° corner.
fn issue(feed: f64) -> String {
    let (x1, y1) = step(0.0, 30.0, 130.0, 15.0);
    let (x2, y2) = step(x1, y1, 220.0, 15.0);
    format!(
        "G90 G17 G94\nG1 X0 Y15 F{feed}\nG3 X0 Y15 I-10 J0\nG1 Y30\nG1 X{x1} Y{y1}\nG1 X{x2} Y{y2}\n"
    )
}

/// Lines meeting a half circle R 10 at 90° corners.
fn arcline(feed: f64) -> String {
    format!("G90 G17 G94\nG1 X20 F{feed}\nG2 X40 Y0 I10 J0\nG1 X55\n")
}

/// The path turns by 140°, then by 90°.
fn acute(feed: f64) -> String {
    let (x1, y1) = step(20.0, 0.0, 140.0, 15.0);
    let (x2, y2) = step(x1, y1, 230.0, 10.0);
    format!("G90 G17 G94\nG1 X20 F{feed}\nG1 X{x1} Y{y1}\nG1 X{x2} Y{y2}\n")
}

/// A closed 10 mm square.
fn square(feed: f64) -> String {
    format!("G90 G17 G94\nG1 X10 F{feed}\nG1 Y10\nG1 X0\nG1 Y0\n")
}

type Maker = fn(f64) -> String;

fn main() {
    let only: Option<String> = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let programs: [(&str, Maker); 5] = [
        ("stair", stair),
        ("issue", issue),
        ("arcline", arcline),
        ("acute", acute),
        ("square", square),
    ];
    let opts = PredistortOptions {
        period_s: 1e-3,
        max_iterations: 30,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
    };
    let (mut met, mut cases) = (0, 0);
    println!("program  F      kv   dw-RMS  max    duration  gates    wall     vs one prediction");
    for (name, make) in programs {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        for feed in [1000.0, 2000.0, 3000.0] {
            for kv in [30.0, 45.0, 60.0] {
                let m = machine(kv);
                let prog = gcode::parse(&make(feed)).expect("program");
                let t = Instant::now();
                predict_program(&m, &prog, 1e-3, 10_000_000).expect("predict");
                let base = t.elapsed().as_secs_f64();
                let t = Instant::now();
                let out = predistort(&m, &prog, &opts).expect("predistort");
                let wall = t.elapsed().as_secs_f64();
                let (o, c) = (out.original, out.compensated);
                let r = c.rms_distance_mm / o.rms_distance_mm;
                let mx = c.max_mm / o.max_mm;
                let d = c.duration_s / o.duration_s;
                let ok = r <= 0.3
                    && mx <= 0.5
                    && d <= DEFAULT_MAX_DURATION_RATIO
                    && c.gouge_mm <= o.gouge_mm.max(1e-3);
                cases += 1;
                met += usize::from(ok);
                println!(
                    "{name:8} {feed:<6} {kv:<4} {r:.3}×  {mx:.3}×  {d:.3}×    {}  {wall:6.2} s  {:.0}×",
                    if ok { "met    " } else { "NOT MET" },
                    wall / base
                );
            }
        }
    }
    println!("{met} of {cases} cases meet all four gates");
}
