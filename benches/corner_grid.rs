//! Issue 39 item 3's gates over the corner grid and a held-out set.
//!
//! Grid: five corner programs (the 2 mm staircase, a circle + 140° + 90° contour,
//! line–half circle–line, a 140° turn + 90° corner, a 10 mm square) at F 1000, 2000 and
//! 3000 mm/min on axes of kv 30, 45 and 60 (the demo cascade otherwise). Held-out:
//! `tests/data/programs/heldout/*.nc`, programs no tuning used, each with its own cascade,
//! acceleration limit and period in a `(machine: …)` comment (other planes: the G18
//! profile). Every answer goes through `contour_program` (written, read back, simulated on
//! the model set). Per case: nominal distance-weighted RMS and max ratios (gates ≤ 0.3×,
//! ≤ 0.5×), the worst over the model set (≤ 0.5×, ≤ 0.7×), the duration (≤ 1.15×), blocks
//! before and after, and the wall time against one plain prediction of the original in the
//! same run.
//!
//! Every program first places X and Y (`G0 X0 Y0`, where the reader starts anyway), as a
//! CAM program does: a corner on an axis the program never placed is only slowed, since
//! the written program cannot state that axis (the machine may be anywhere on it).
//!
//! Run: `cargo bench --bench corner_grid`; `-- stair` runs one program, `-- heldout` the
//! held-out set only; `-- --notes` prints each answer's notes and warnings.

use std::time::Instant;

use serde_json::json;
use truecut::cam::{
    DEFAULT_BAND_MM, DEFAULT_MAX_DURATION_RATIO, MAX_ITERATIONS, PredistortOptions, contour_program,
};
use truecut::motion::{Machine, ReadOptions, gcode, predict_program};

/// The demo cascade with `kv`, or a held-out header's values.
fn machine(kv: f64, kff: f64, kp_v: f64, ti_v: f64, tc: f64, accel: Option<f64>) -> Machine {
    let mut ax = json!({"kv": kv, "kff": kff, "kp_v": kp_v, "ti_v": ti_v, "tc": tc});
    if let Some(a) = accel {
        ax["max_accel"] = json!(a);
    }
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

fn stair(feed: f64) -> String {
    let mut p = format!("G90 G17 G94\nG0 X0 Y0\nG1 X2 F{feed}\n");
    for k in 1..=5 {
        p += &format!("G1 Y{}\nG1 X{}\n", 2 * k, 2 * k + 2);
    }
    p
}

fn issue(feed: f64) -> String {
    let (x1, y1) = step(0.0, 30.0, 130.0, 15.0);
    let (x2, y2) = step(x1, y1, 220.0, 15.0);
    format!(
        "G90 G17 G94\nG0 X0 Y0\nG1 X0 Y15 F{feed}\nG3 X0 Y15 I-10 J0\nG1 Y30\nG1 X{x1} Y{y1}\nG1 X{x2} Y{y2}\n"
    )
}

fn arcline(feed: f64) -> String {
    format!("G90 G17 G94\nG0 X0 Y0\nG1 X20 F{feed}\nG2 X40 Y0 I10 J0\nG1 X55\n")
}

fn acute(feed: f64) -> String {
    let (x1, y1) = step(20.0, 0.0, 140.0, 15.0);
    let (x2, y2) = step(x1, y1, 230.0, 10.0);
    format!("G90 G17 G94\nG0 X0 Y0\nG1 X20 F{feed}\nG1 X{x1} Y{y1}\nG1 X{x2} Y{y2}\n")
}

fn square(feed: f64) -> String {
    format!("G90 G17 G94\nG0 X0 Y0\nG1 X10 F{feed}\nG1 Y10\nG1 X0\nG1 Y0\n")
}

type Maker = fn(f64) -> String;

/// Counts of cases meeting the gates.
#[derive(Default)]
struct Tally {
    cases: usize,
    nominal: usize,
    worst: usize,
    duration: usize,
    all: usize,
}

fn run(name: &str, text: &str, m: &Machine, period_s: f64, tally: &mut Tally) {
    let prog = gcode::parse(text).expect("program");
    let t = Instant::now();
    predict_program(m, &prog, period_s, 10_000_000).expect("predict");
    let base = t.elapsed().as_secs_f64();
    let opts = PredistortOptions {
        period_s,
        max_iterations: MAX_ITERATIONS,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
        band_mm: DEFAULT_BAND_MM,
    };
    let t = Instant::now();
    let (out, p) = contour_program(text, &ReadOptions::default(), m, &opts).expect("contour");
    let wall = t.elapsed().as_secs_f64();
    let ratio = |f: &truecut::cam::ModelFigures| {
        (
            f.compensated.rms_distance_mm / f.original.rms_distance_mm,
            f.compensated.max_mm / f.original.max_mm,
        )
    };
    let (r, mx) = ratio(&p.models[0]);
    let (wr, wm) = p
        .models
        .iter()
        .map(ratio)
        .fold((0.0f64, 0.0f64), |a, b| (a.0.max(b.0), a.1.max(b.1)));
    let d = p.compensated.duration_s / p.original.duration_s;
    let ok_n = r <= 0.3 && mx <= 0.5;
    let ok_w = wr <= 0.5 && wm <= 0.7;
    let ok_d = d <= DEFAULT_MAX_DURATION_RATIO + 1e-9;
    tally.cases += 1;
    tally.nominal += usize::from(ok_n);
    tally.worst += usize::from(ok_w);
    tally.duration += usize::from(ok_d);
    tally.all += usize::from(ok_n && ok_w && ok_d);
    let blocks_in = text.lines().filter(|l| !l.trim().is_empty()).count();
    println!(
        "{name:28} {r:.3}x {mx:.3}x | {wr:.3}x {wm:.3}x | {d:.3}x | {} | {blocks_in:>3} -> {:>3} | \
         {wall:6.2} s {:5.0}x",
        if ok_n && ok_w && ok_d {
            "met    "
        } else {
            "NOT MET"
        },
        out.blocks,
        wall / base
    );
    if std::env::args().any(|a| a == "--notes") {
        for n in p.notes.iter().chain(&out.warnings) {
            println!("    {n}");
        }
    }
}

/// The `(machine: k=v …)` header of a held-out program.
fn header(text: &str) -> (Machine, f64) {
    let line = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("(machine:"))
        .expect("held-out program without a (machine: ...) header");
    let get = |k: &str| -> f64 {
        line.trim_end_matches(')')
            .split_whitespace()
            .find_map(|kv| kv.strip_prefix(&format!("{k}=")))
            .unwrap_or_else(|| panic!("header lacks {k}"))
            .parse()
            .expect("number")
    };
    (
        machine(
            get("kv"),
            get("kff"),
            get("kp_v"),
            get("ti_v"),
            get("tc"),
            Some(get("max_accel")),
        ),
        get("period"),
    )
}

fn main() {
    let only: Option<String> = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let programs: [(&str, Maker); 5] = [
        ("stair", stair),
        ("issue", issue),
        ("arcline", arcline),
        ("acute", acute),
        ("square", square),
    ];
    println!(
        "case                         nominal RMS max | worst RMS max | duration | gates | blocks | wall, vs one prediction"
    );
    let mut grid = Tally::default();
    for (name, make) in programs {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        for feed in [1000.0, 2000.0, 3000.0] {
            for kv in [30.0, 45.0, 60.0] {
                let m = machine(kv, 0.6, 400.0, 0.01, 0.0005, None);
                run(
                    &format!("{name} F{feed} kv{kv}"),
                    &make(feed),
                    &m,
                    1e-3,
                    &mut grid,
                );
            }
        }
    }
    let mut held = Tally::default();
    if only.as_deref().is_none_or(|o| o == "heldout") {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/programs/heldout");
        let mut files: Vec<_> = std::fs::read_dir(dir)
            .expect("held-out set")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "nc"))
            .collect();
        files.sort();
        for f in files {
            let text = std::fs::read_to_string(&f).expect("read");
            let (m, period) = header(&text);
            let name = f.file_stem().unwrap().to_string_lossy().to_string();
            run(&format!("heldout/{name}"), &text, &m, period, &mut held);
        }
    }
    for (label, t) in [("grid", &grid), ("held-out", &held)] {
        if t.cases > 0 {
            println!(
                "{label}: {} of {} meet all gates (nominal {}, worst of set {}, duration {})",
                t.all, t.cases, t.nominal, t.worst, t.duration
            );
        }
    }
}
