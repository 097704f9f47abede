//! Unit tests of `crate::motion::interpolate::controller`: the controller's limits on dense
//! blocks (LinuxCNC's segment cap, a block rate, a look-ahead depth) with the figures the
//! module documents, and no change without them.

use super::super::{Trajectory, interpolate};
use crate::motion::gcode::parse;
use crate::motion::machine::Machine;
use crate::motion::profile;
use serde_json::{Value, json};

/// X, Y, Z with the default limits (500 mm/s, 5000 mm/s², 100,000 mm/s³) and `controller`.
fn machine(controller: Option<Value>) -> Machine {
    let ax = json!({"kv": 30});
    let mut def = json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}});
    if let Some(c) = controller {
        def["controller"] = c;
    }
    Machine::from_json(&def).unwrap()
}

fn run(m: &Machine, text: &str) -> Trajectory {
    interpolate(&parse(text).unwrap(), m, 1e-3, 10_000_000).unwrap()
}

/// Largest path speed over one period, mm/s.
fn top_speed(t: &Trajectory) -> f64 {
    top_speed_until(t, u32::MAX)
}

/// Largest path speed over the periods that end on source lines up to `line`, mm/s.
fn top_speed_until(t: &Trajectory, line: u32) -> f64 {
    (1..t.t.len())
        .filter(|&k| t.line[k] <= line)
        .map(|k| {
            let d2: f64 = t.axes.iter().map(|c| (c[k] - c[k - 1]).powi(2)).sum();
            d2.sqrt() / t.period_s
        })
        .fold(0.0, f64::max)
}

/// `n` collinear G1 blocks of `len` mm along X at F6000 (100 mm/s).
fn chords(n: usize, len: f64) -> String {
    let mut g = String::from("G1 F6000\n");
    for k in 1..=n {
        g += &format!("X{:.4}\n", k as f64 * len);
    }
    g
}

/// 1,000 chords of 20 µm at a 1 ms period: LinuxCNC runs each at most 0.020/(1.02·0.001) =
/// 19.6 mm/s; the service's own planning runs the 20 mm line at F (100 mm/s).
#[test]
fn linuxcnc_caps_a_segment_at_its_length_over_1_02_periods() {
    let prog = chords(1000, 0.02);
    let free = top_speed(&run(&machine(None), &prog));
    let t = run(&machine(Some(json!({"kind": "linuxcnc"}))), &prog);
    let capped = top_speed(&t);
    let cap = 0.02 / (1.02 * 1e-3);
    assert!((free - 100.0).abs() < 1e-6, "without a controller {free}");
    assert!(
        capped <= cap * (1.0 + 1e-9) && capped > 0.99 * cap,
        "{capped} vs {cap}"
    );
    assert!(capped <= 19.61);
    // A grbl-kind controller has no segment cap unless it says so.
    let grbl = top_speed(&run(&machine(Some(json!({"kind": "grbl"}))), &prog));
    assert!((grbl - 100.0).abs() < 1e-6);
    let off = json!({"kind": "linuxcnc", "segment_cap": false});
    assert!((top_speed(&run(&machine(Some(off)), &prog)) - 100.0).abs() < 1e-6);
    eprintln!(
        "1000 chords of 20 µm at 1 ms: {capped:.3} mm/s on LinuxCNC (cap {cap:.3}), {free:.1} \
         mm/s without; {:.3} s",
        t.t.last().unwrap()
    );
}

/// 1000 blocks a second over 20 µm blocks: at most 0.020 · 1000 = 20 mm/s.
#[test]
fn a_block_rate_caps_the_speed_at_length_times_rate() {
    let prog = chords(1000, 0.02);
    let m = machine(Some(json!({"kind": "grbl", "block_rate_hz": 1000})));
    let v = top_speed(&run(&m, &prog));
    assert!(v <= 20.0 * (1.0 + 1e-9) && v > 19.8, "{v}");
    // Blocks long enough for the rate run at F: 1 mm blocks allow 1000 mm/s.
    let v = top_speed(&run(&m, &chords(20, 1.0)));
    assert!((v - 100.0).abs() < 1e-6, "{v}");
    eprintln!(
        "1000 blocks/s over 20 µm blocks: {:.3} mm/s",
        top_speed(&run(&m, &prog))
    );
}

/// A planner that sees 5 blocks of 0.1 mm must stop within 0.5 mm: the approach to a sharp
/// corner (a reversal) runs at most at the speed that stops in 0.5 mm with the axis' caps,
/// v^{3/2}/√j = 0.5 mm (triangular jerk ramp): 29.2 mm/s, against F (100 mm/s) with the
/// whole program in view.
#[test]
fn a_lookahead_depth_caps_the_approach_at_what_stops_within_the_window() {
    let mut prog = chords(200, 0.1);
    prog += "X0\n";
    let v_stop = profile::max_reachable_speed(0.0, 0.5, 5000.0, 100_000.0);
    assert!((v_stop - 29.24).abs() < 0.01, "{v_stop}");
    // Lines 2..=201 are the chords, line 202 the reversal back along them.
    let free = top_speed_until(&run(&machine(None), &prog), 201);
    let m = machine(Some(json!({"kind": "generic", "lookahead_blocks": 5})));
    let t = run(&m, &prog);
    let approach = top_speed_until(&t, 201);
    assert!((free - 100.0).abs() < 1e-6, "{free}");
    // Within a 0.1 mm block the S-curve may rise a hair above the junction speed, never
    // above what stops within the window seen from the block's start (0.6 mm).
    let v_start = profile::max_reachable_speed(0.0, 0.6, 5000.0, 100_000.0);
    assert!(
        approach > 0.99 * v_stop && approach <= v_start,
        "{approach} vs {v_stop}"
    );
    assert!(approach <= v_stop * 1.005, "{approach} vs {v_stop}");
    eprintln!(
        "look-ahead 5 blocks of 0.1 mm: approach {approach:.2} mm/s (stops in 0.5 mm: \
         {v_stop:.2}), {free:.1} mm/s with the whole program in view"
    );
}

/// A controller object that states no limit plans exactly as no controller.
#[test]
fn a_controller_without_limits_changes_nothing() {
    let prog = format!(
        "{}G1 Y5\nG2 X-9 Y15 I-10 J0\nG4 P100\nG0 X50\n",
        chords(50, 0.02)
    );
    let base = run(&machine(None), &prog);
    let same = run(&machine(Some(json!({"kind": "generic"}))), &prog);
    assert!(base == same);
}
