//! Unit tests of `crate::motion::interpolate::modes`: exact stop (G61, G61.1, G9, look-ahead
//! off) and G64 P blending, through the reader ([`parse_modes`]) and the interpolator.

use super::super::{Trajectory, interpolate_with};
use crate::motion::gcode::{ReadOptions, parse_modes};
use crate::motion::machine::Machine;
use serde_json::json;

/// X, Y, Z with the default limits: 500 mm/s, 5000 mm/s², 100,000 mm/s³.
fn machine() -> Machine {
    let ax = json!({"kv": 30});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

fn run(text: &str) -> Trajectory {
    let (program, control, _) = parse_modes(text, &ReadOptions::default()).unwrap();
    interpolate_with(&program, &control, &machine(), 1e-3, 10_000_000).unwrap()
}

/// Path speed (mm/s) over the period ending at each sample (index 0: 0).
fn speeds(t: &Trajectory) -> Vec<f64> {
    let mut out = vec![0.0];
    for k in 1..t.t.len() {
        let d2: f64 = t.axes.iter().map(|c| (c[k] - c[k - 1]).powi(2)).sum();
        out.push(d2.sqrt() / t.period_s);
    }
    out
}

/// The smallest speed over the periods that end within `reach` mm of `x` on axis X.
fn speed_near_x(t: &Trajectory, x: f64, reach: f64) -> f64 {
    let v = speeds(t);
    (1..t.t.len())
        .filter(|&k| (t.axes[0][k] - x).abs() <= reach || (t.axes[0][k - 1] - x).abs() <= reach)
        .map(|k| v[k])
        .fold(f64::INFINITY, f64::min)
}

/// A jerk-limited stop reaches speed 0 with zero acceleration: over the period that holds
/// the stop the mean speed is at most jerk·period²/2 = 0.05 mm/s; a junction the look-ahead
/// runs through keeps the feed (100 mm/s) on a straight line.
const STOPPED_MM_S: f64 = 0.1;

#[test]
fn exact_stop_modes_bring_the_speed_to_zero_at_every_block_end_they_govern() {
    let line = "G1 X10 F6000\nG1 X20\nG1 X30\n";
    let cont = run(line);
    assert!(speed_near_x(&cont, 10.0, 0.05) > 99.0);
    assert!(speed_near_x(&cont, 20.0, 0.05) > 99.0);
    for mode in ["G61", "G61.1", "G05.1 Q0", "G08 P0", "G64 G08 P0"] {
        let t = run(&format!("{mode}\n{line}"));
        for x in [10.0, 20.0] {
            let v = speed_near_x(&t, x, 0.05);
            assert!(v < STOPPED_MM_S, "{mode}: {v} mm/s at X{x}");
        }
        assert!(t.t.last() > cont.t.last(), "{mode}: stops take time");
        eprintln!(
            "{mode}: 3 x 10 mm at F6000 in {:.3} s against {:.3} s in the look-ahead",
            t.t.last().unwrap(),
            cont.t.last().unwrap()
        );
    }
    // G9 stops its own block only; G64 cancels G61; G05.1 Q1 switches look-ahead back on.
    let t = run("G9 G1 X10 F6000\nG1 X20\nG1 X30\n");
    assert!(speed_near_x(&t, 10.0, 0.05) < STOPPED_MM_S);
    assert!(speed_near_x(&t, 20.0, 0.05) > 99.0);
    let t = run("G61\nG1 X10 F6000\nG64\nG1 X20\nG1 X30\n");
    assert!(speed_near_x(&t, 10.0, 0.05) < STOPPED_MM_S);
    assert!(speed_near_x(&t, 20.0, 0.05) > 99.0);
    let t = run("G05.1 Q0\nG1 X10 F6000\nG05.1 Q1\nG1 X20\nG1 X30\n");
    assert!(speed_near_x(&t, 10.0, 0.05) < STOPPED_MM_S);
    assert!(speed_near_x(&t, 20.0, 0.05) > 99.0);
}

/// Distance (mm) from `p` to the segment `a`–`b` in XY.
fn to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let u = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
    (p[0] - a[0] - u * dx).hypot(p[1] - a[1] - u * dy)
}

/// G64 P0.05 on a 90° corner at 6 m/min: the commanded path passes within 0.05 mm of the
/// programmed corner and never leaves the programmed path by more than 0.05 mm, and the
/// corner is taken faster than the look-ahead's corner rule allows without blending
/// (9.0 against 4.6 mm/s; 1.137 s against 1.122 s for the whole program).
#[test]
fn g64_p_blends_a_corner_within_its_tolerance_and_passes_it_faster() {
    let corner = "G1 X50 F6000\nG1 Y50\n";
    let sharp = run(corner);
    let blended = run(&format!("G64 P0.05\n{corner}"));
    let path = |t: &Trajectory| -> (f64, f64) {
        let (mut off_path, mut to_corner) = (0.0f64, f64::INFINITY);
        for k in 0..t.t.len() {
            let p = [t.axes[0][k], t.axes[1][k]];
            let d = to_segment(p, [0.0, 0.0], [50.0, 0.0]).min(to_segment(
                p,
                [50.0, 0.0],
                [50.0, 50.0],
            ));
            off_path = off_path.max(d);
            to_corner = to_corner.min((p[0] - 50.0).hypot(p[1]));
        }
        (off_path, to_corner)
    };
    let (off_path, to_corner) = path(&blended);
    // LinuxCNC's tolerance is the arc midpoint's distance from the corner (blendmath.c:
    // h − R = T); the path itself is then T·cos 45° = 0.035 mm from the programmed lines.
    assert!(off_path <= 0.05, "left the path by {off_path} mm");
    // The samples straddle the arc's midpoint (17 µm apart on a 0.12 mm radius).
    assert!(off_path >= 0.03, "{off_path}");
    assert!(
        (0.05 - 1e-9..=0.05 + 3e-3).contains(&to_corner),
        "closest to the corner {to_corner} mm"
    );
    assert!(
        path(&sharp).0 < 1e-12,
        "without blending the path is the program's"
    );
    // Speed at the corner: the slowest period near it.
    let slowest = |t: &Trajectory| -> f64 {
        let v = speeds(t);
        (1..t.t.len())
            .filter(|&k| (t.axes[0][k] - 50.0).hypot(t.axes[1][k]) < 1.0)
            .map(|k| v[k])
            .fold(f64::INFINITY, f64::min)
    };
    let (v_sharp, v_blend) = (slowest(&sharp), slowest(&blended));
    // Without blending: max_accel·period per unit direction change = 5 mm/s. With it: the arc
    // of radius R = tan 45°·cos 45°·0.05/(1 − sin 45°) = 0.1207 mm at the interpolator's arc
    // speed min(√(a/2·R), ∛(j/2·R²)) = min(17.4, 9.01) mm/s (jerk-bound on so small a radius).
    assert!(v_sharp <= 5.0 + 1e-6, "sharp corner at {v_sharp}");
    let r = 0.120_710_678f64;
    let v_arc = (2500.0 * r).sqrt().min((50_000.0 * r * r).cbrt());
    assert!(
        (v_blend - v_arc).abs() < 0.05 * v_arc,
        "{v_blend} vs {v_arc}"
    );
    // The program takes a little longer all the same: the look-ahead's corner rule lets the
    // speed dip for one period, the jerk-limited arc holds its speed over 0.19 mm.
    eprintln!(
        "G64 P0.05 90° corner at F6000: off the path {off_path:.4} mm, closest to the corner \
         {to_corner:.4} mm; corner speed {v_blend:.2} mm/s vs {v_sharp:.2} mm/s unblended; \
         {:.4} s vs {:.4} s",
        blended.t.last().unwrap(),
        sharp.t.last().unwrap()
    );
}

#[test]
fn g64_without_p_or_with_p0_plans_as_before() {
    let corner = "G1 X50 F6000\nG1 Y50\n";
    let base = run(corner);
    for modes in ["G64", "G64 P0", "G05.1 Q1\nG08 P1"] {
        let t = run(&format!("{modes}\n{corner}"));
        assert!(t.axes == base.axes, "{modes} changed the command");
    }
    // A blend tolerance that G61 overrides, then G64 P restores.
    let t = run(&format!("G64 P0.05\nG61\n{corner}"));
    assert!(speed_near_x(&t, 50.0, 1e-6) < STOPPED_MM_S);
}
