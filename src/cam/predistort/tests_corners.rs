//! Unit tests of the corner stage (issue 24): corner programs (90° and 140° corners, short
//! segments, arc–line junctions, F 1000–3000, kv 30–60) against the goals, with the figures
//! printed beside them.

use super::*;
use crate::motion::{gcode, interpolate};
use serde_json::json;

/// The demo cascade (kff 0.6, PI velocity loop, 0.5 ms current loop) with position-loop
/// gain `kv` (1/s) on X, Y, Z, default limits (500 mm/s, 5 m/s², 100 m/s³).
fn machine_kv(kv: f64) -> Machine {
    let ax = json!({"kv": kv, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

/// A point `len` mm from `(x, y)` in direction `deg` (degrees from +X), 4 decimals.
fn step(x: f64, y: f64, deg: f64, len: f64) -> (f64, f64) {
    let r = deg.to_radians();
    (
        ((x + len * r.cos()) * 1e4).round() / 1e4,
        ((y + len * r.sin()) * 1e4).round() / 1e4,
    )
}

/// Issue 24's finishing contour: a full circle R 10 entered and left tangentially, then a
/// 140° corner (the path turns by 40°) and a 90° corner, 15 mm legs.
fn issue_program(feed: f64) -> String {
    let (x1, y1) = step(0.0, 30.0, 90.0 + 40.0, 15.0);
    let (x2, y2) = step(x1, y1, 90.0 + 40.0 + 90.0, 15.0);
    format!(
        "G90 G17 G94\nG1 X0 Y15 F{feed}\nG3 X0 Y15 I-10 J0\nG1 Y30\nG1 X{x1} Y{y1}\nG1 X{x2} Y{y2}\n"
    )
}

/// The 40 mm square with a 20° kink in the middle of the first side (BENCHMARKS.md).
const KINKED_SQUARE: &str =
    "G90 G17 G94\nG0 X0 Y0\nG1 X20 Y3.5 F3000\nG1 X40 Y0\nG1 Y40\nG1 X0\nG1 Y0\n";

/// A staircase of 2 mm steps: short segments with 90° corners turning left and right.
fn staircase(feed: f64) -> String {
    let mut p = format!("G90 G17 G94\nG1 X2 F{feed}\n");
    for k in 1..=5 {
        p += &format!("G1 Y{}\nG1 X{}\n", 2 * k, 2 * k + 2);
    }
    p
}

/// Lines meeting a half circle R 10 at 90° corners on both ends.
fn arc_line(feed: f64) -> String {
    format!("G90 G17 G94\nG1 X20 F{feed}\nG2 X40 Y0 I10 J0\nG1 X55\n")
}

/// An acute corner: the path turns by 140° (40° between the legs), then a 90° corner.
fn acute(feed: f64) -> String {
    let (x1, y1) = step(20.0, 0.0, 140.0, 15.0);
    let (x2, y2) = step(x1, y1, 230.0, 10.0);
    format!("G90 G17 G94\nG1 X20 F{feed}\nG1 X{x1} Y{y1}\nG1 X{x2} Y{y2}\n")
}

/// A 10 mm square, four 90° corners (left turns), closed.
fn square(feed: f64) -> String {
    format!("G90 G17 G94\nG1 X10 F{feed}\nG1 Y10\nG1 X0\nG1 Y0\n")
}

/// Programmed feed (mm/min) of the block of `line`.
fn feed_of_line(m: &Machine, prog: &gcode::Program, line: usize) -> f64 {
    let b = prog.blocks.iter().find(|b| b.line == line).unwrap();
    match b.feed {
        gcode::Feed::PerMinute(f) => f,
        gcode::Feed::Rapid => m.rapid_mm_min,
        gcode::Feed::InverseTime(_) => unreachable!(),
    }
}

/// Runs the pre-distortion (material side `side` for every line, `None`: the rule for
/// programs without G41/G42), prints original vs compensated beside the goals, re-simulates
/// the emitted points from text, and checks issue 24's constraints (duration ≤ 1.15×, no
/// feed lowered beyond the original's own speed, no gouge beyond 1 µm or the original's)
/// and the error gates (distance-weighted RMS ≤ 0.3×, max ≤ 0.5×).
fn check_corner_goals(name: &str, kv: f64, text: &str, side: Option<MaterialSide>) -> Predistorted {
    check_corner_goals_within(name, kv, text, side, DEFAULT_MAX_DURATION_RATIO)
}

/// [`check_corner_goals`] with the duration allowed up to `ratio` × the original's (the
/// request's `max_duration_ratio`; the duration gate becomes `ratio`).
fn check_corner_goals_within(
    name: &str,
    kv: f64,
    text: &str,
    side: Option<MaterialSide>,
    ratio: f64,
) -> Predistorted {
    // Issue 24's distance-weighted RMS gate.
    let rms_gate = 0.3;
    let m = machine_kv(kv);
    let prog = gcode::parse(text).unwrap();
    let opts = PredistortOptions {
        period_s: 1e-3,
        max_iterations: 30,
        max_duration_ratio: ratio,
    };
    let t0 = std::time::Instant::now();
    let out = predistort_sided(&m, &prog, &opts, &|_| false, &|_| side).unwrap();
    let wall = t0.elapsed().as_secs_f64();
    let (o, c) = (out.original, out.compensated);
    println!(
        "{name} (kv {kv}): distance-weighted RMS {:.2} → {:.2} µm ({:.3}×, goal ≤ 0.1×, gate ≤ 0.3×); \
         max {:.2} → {:.2} µm ({:.3}×, gate ≤ 0.5×); per-period RMS {:.2} → {:.2} µm; \
         duration {:.3} → {:.3} s ({:.3}×, gate ≤ {ratio}×); gouge {:.2} → {:.2} µm (gate ≤ 1 µm); \
         {} points, {} simulations, {wall:.2} s",
        o.rms_distance_mm * 1e3,
        c.rms_distance_mm * 1e3,
        c.rms_distance_mm / o.rms_distance_mm,
        o.max_mm * 1e3,
        c.max_mm * 1e3,
        c.max_mm / o.max_mm,
        o.rms_mm * 1e3,
        c.rms_mm * 1e3,
        o.duration_s,
        c.duration_s,
        c.duration_s / o.duration_s,
        o.gouge_mm * 1e3,
        c.gouge_mm * 1e3,
        out.points.len(),
        out.iterations
    );
    let met = |ok: bool| if ok { "met" } else { "NOT MET" };
    let gates = [
        c.rms_distance_mm <= rms_gate * o.rms_distance_mm,
        c.max_mm <= 0.5 * o.max_mm,
        c.duration_s <= ratio * o.duration_s,
        c.gouge_mm <= GOUGE_LIMIT_MM.max(o.gouge_mm),
    ];
    println!(
        "  gates: RMS ≤ {rms_gate}× {}, max ≤ 0.5× {}, duration ≤ {ratio}× {}, no gouge on the material \
         side (≤ 1 µm, or the original's where it cuts the turn) {}",
        met(gates[0]),
        met(gates[1]),
        met(gates[2]),
        met(gates[3])
    );
    for n in &out.notes {
        println!("  note: {n}");
    }
    // No block's programmed feed lowered, except where the original itself ran slower
    // (its junction limit): there the block's F is at least the original's top speed over
    // the stretch of path the block spans (nearest original samples to its ends).
    let cmd = interpolate(&prog, &m, 1e-3, MAX_PERIODS).unwrap();
    let at = |i: usize| [cmd.axes[0][i], cmd.axes[1][i], cmd.axes[2][i]];
    let nearest = |p: &[f64], line: usize| {
        (0..cmd.t.len())
            .filter(|&i| cmd.line[i] as usize == line)
            .min_by(|&a, &b| {
                let d = |i: usize| norm(sub(at(i), [p[0], p[1], p[2]]));
                d(a).total_cmp(&d(b))
            })
            .unwrap()
    };
    let mut slowed = 0;
    let mut prev = vec![0.0; 3];
    for p in &out.points {
        let f = feed_of_line(&m, &prog, p.line);
        if p.feed_mm_min < f {
            slowed += 1;
            // The block's span on the original: its samples of the same line nearest to
            // its two ends (a point carried past a corner is nearest to the corner).
            let (a, b) = (nearest(&prev, p.line), nearest(&p.axes, p.line));
            let top = (a.min(b)..=a.max(b).min(cmd.t.len() - 2))
                .map(|i| norm(sub(at(i + 1), at(i))) / 1e-3)
                .fold(0.0, f64::max);
            assert!(
                p.feed_mm_min / 60.0 >= 0.995 * top,
                "line {}: F{} below the original's {top} mm/s there",
                p.line,
                p.feed_mm_min
            );
        }
        prev = p.axes.clone();
    }
    println!("  {slowed} blocks below the programmed F, each at the original's own speed there");
    // Every feed line keeps a point: the contour route writes a line without one as
    // programmed, which the points simulated here would not show.
    for b in prog
        .blocks
        .iter()
        .filter(|b| !matches!(b.feed, gcode::Feed::Rapid))
    {
        assert!(
            out.points.iter().any(|p| p.line == b.line),
            "{name}: line {} has no point",
            b.line
        );
    }
    // The emitted text, read back, interpolated and simulated, gives the same figures.
    let mut g = String::from("G90 G94\n");
    for p in &out.points {
        g += &format!(
            "G1 X{:.4} Y{:.4} Z{:.4} F{:.3}\n",
            p.axes[0], p.axes[1], p.axes[2], p.feed_mm_min
        );
        if p.dwell_s > 0.0 {
            g += &format!("G4 P{}\n", (p.dwell_s * 1e3).round());
        }
    }
    assert!(
        side.is_some() || out.points.iter().all(|p| p.dwell_s == 0.0),
        "{name}: a stop at an outside corner"
    );
    let stops: Vec<String> = out
        .points
        .iter()
        .filter(|p| p.dwell_s > 0.0)
        .map(|p| format!("line {} {:.0} ms", p.line, p.dwell_s * 1e3))
        .collect();
    if !stops.is_empty() {
        println!("  stops at inside corners: {}", stops.join(", "));
    }
    let periods = interpolate(&gcode::parse(&g).unwrap(), &m, 1e-3, MAX_PERIODS)
        .unwrap()
        .t
        .len();
    assert!((periods as f64 * 1e-3 - c.duration_s).abs() < 1e-9);
    assert!(o.max_mm > 1e-3, "the original must have an error to remove");
    let (rms, max) = (rms_gate, 0.5);
    assert!(
        c.rms_distance_mm <= rms * o.rms_distance_mm,
        "{name}: distance-weighted RMS {} vs {}",
        c.rms_distance_mm,
        o.rms_distance_mm
    );
    assert!(
        c.max_mm <= max * o.max_mm,
        "{name}: max {} vs {}",
        c.max_mm,
        o.max_mm
    );
    assert!(
        c.duration_s <= ratio * o.duration_s,
        "{name}: duration {} vs {}",
        c.duration_s,
        o.duration_s
    );
    assert!(
        c.gouge_mm <= GOUGE_LIMIT_MM.max(o.gouge_mm),
        "{name}: gouge {} mm (original {})",
        c.gouge_mm,
        o.gouge_mm
    );
    out
}

#[test]
fn issue_contour_meets_the_corner_goals() {
    check_corner_goals(
        "circle + 140° + 90° corners F2000",
        40.0,
        &issue_program(2000.0),
        None,
    );
}

#[test]
fn kinked_square_meets_the_corner_goals() {
    check_corner_goals("square with 20° kinks F3000", 30.0, KINKED_SQUARE, None);
}

/// Short segments: 2 mm steps, 90° corners turning left and right.
#[test]
fn short_segments_improve() {
    check_corner_goals("2 mm staircase F1000", 60.0, &staircase(1000.0), None);
    // Ten corners 2 mm apart: the three split points and the corner-window ILC reach only
    // 0.66× within 1.15× the time (each corner passes at the 5 mm/s junction speed and the
    // tool needs 1/kv = 25 ms to catch up); smooth loops of 20 µm chords (module `loops`)
    // turn the corners at the speed their curvature allows and meet the gates.
    check_corner_goals("2 mm staircase F2000", 40.0, &staircase(2000.0), None);
    // The same program with more time allowed (the request's max_duration_ratio 1.3): the
    // error falls further.
    check_corner_goals_within(
        "2 mm staircase F2000, max_duration_ratio 1.3",
        40.0,
        &staircase(2000.0),
        None,
        1.3,
    );
}

/// The 2 mm staircase at the slow end of issue 24's gains (kv 30), F 2000 and F 3000
/// (`cargo bench --bench corner_grid`: 0.148× / 0.224× and 0.197× / 0.332× RMS / max).
#[test]
fn short_segments_on_slow_axes() {
    check_corner_goals("2 mm staircase F2000", 30.0, &staircase(2000.0), None);
    check_corner_goals("2 mm staircase F3000", 30.0, &staircase(3000.0), None);
}

/// The 2 mm staircase on stiffer axes, F 2000 on kv 45 and 60, F 3000 on kv 45 (0.103× /
/// 0.264×, 0.063× / 0.216×, 0.130× / 0.154× RMS / max).
#[test]
fn short_segments_on_stiff_axes() {
    check_corner_goals("2 mm staircase F2000", 60.0, &staircase(2000.0), None);
    check_corner_goals("2 mm staircase F2000", 45.0, &staircase(2000.0), None);
    check_corner_goals("2 mm staircase F3000", 45.0, &staircase(3000.0), None);
}

/// The 2 mm staircase at F 3000 on kv 60, the last case of issue 24's range to meet the
/// gates. Until the interpolator carried the acceleration across the loops' chords it ended
/// at 0.456× RMS / 0.433× max with the duration budget binding: each 20 µm chord restarted
/// its speed ramp from zero acceleration, so the loops and the points around them ran at one
/// speed and could not win back the time the corners cost. Now 0.137× / 0.220× / 1.143×.
#[test]
fn short_segments_at_full_feed_on_stiff_axes() {
    check_corner_goals("2 mm staircase F3000", 60.0, &staircase(3000.0), None);
}

/// Arcs meeting lines at 90° corners.
#[test]
fn arc_line_corners() {
    check_corner_goals(
        "line–half circle R10–line F3000",
        30.0,
        &arc_line(3000.0),
        None,
    );
    check_corner_goals(
        "line–half circle R10–line F1000",
        50.0,
        &arc_line(1000.0),
        None,
    );
    // The loops run the corners without the original's braking, so the points on the arc
    // before the second corner, pre-distorted for a slow pass, must follow the loops' timing
    // (module `loops::settle`; without it 0.308× / 0.309×, the split points' answer).
    check_corner_goals(
        "line–half circle R10–line F3000",
        60.0,
        &arc_line(3000.0),
        None,
    );
}

/// 140° turns (acute corners) across the feed and gain ranges.
#[test]
fn acute_corners_meet_the_goals() {
    check_corner_goals("140° turn + 90° corner F1500", 50.0, &acute(1500.0), None);
    check_corner_goals("140° turn + 90° corner F1000", 60.0, &acute(1000.0), None);
    check_corner_goals("140° turn + 90° corner F3000", 30.0, &acute(3000.0), None);
    // Loops, then the points between them for the loops' timing (0.367× before).
    check_corner_goals("140° turn + 90° corner F3000", 60.0, &acute(3000.0), None);
}

/// 90° corners across the feed and gain ranges.
#[test]
fn square_corners() {
    check_corner_goals("10 mm square F1000", 30.0, &square(1000.0), None);
    check_corner_goals("10 mm square F3000", 60.0, &square(3000.0), None);
}

/// Inside corners (G41 with left turns: the material lies outside every turn, as in a
/// pocket): the tool must never go more than 1 µm beyond the path outside the turn.
#[test]
fn inside_corners_do_not_gouge() {
    let out = check_corner_goals(
        "10 mm square, inside corners (G41) F2000",
        40.0,
        &square(2000.0),
        Some(MaterialSide::Right),
    );
    assert!(out.compensated.gouge_mm <= GOUGE_LIMIT_MM);
    // The tool stops at each of the three inside corners (the fourth is the program's end),
    // and nowhere else; each stop is named in a note.
    let stops: Vec<(usize, f64)> = out
        .points
        .iter()
        .filter(|p| p.dwell_s > 0.0)
        .map(|p| (p.line, p.dwell_s))
        .collect();
    assert_eq!(
        stops.iter().map(|s| s.0).collect::<Vec<_>>(),
        [2, 3, 4],
        "{stops:?}"
    );
    for (line, s) in &stops {
        assert!(*s <= corners::MAX_STOP_S && (s * 1e3).fract() == 0.0, "{s}");
        assert!(
            out.notes
                .iter()
                .any(|n| n.starts_with(&format!("line {line}: inside corner"))
                    && n.contains(&format!("G4 P{:.0}", s * 1e3))),
            "{:?}",
            out.notes
        );
    }
}

/// Programs the ILC's settings were not chosen on (held out: other sizes, feeds, gains and
/// turns within issue 24's ranges), asserted against the same gates.
#[test]
fn held_out_corner_programs() {
    let sq = |s: f64, f: f64| format!("G90 G17 G94\nG1 X{s} F{f}\nG1 Y{s}\nG1 X0\nG1 Y0\n");
    check_corner_goals("12 mm square F2000", 45.0, &sq(12.0, 2000.0), None);
    check_corner_goals("6 mm square F2500", 35.0, &sq(6.0, 2500.0), None);
    let mut stairs = String::from("G90 G17 G94\nG1 X3 F1500\n");
    for k in 1..=4 {
        stairs += &format!("G1 Y{}\nG1 X{}\n", 3 * k, 3 * k + 3);
    }
    check_corner_goals("3 mm staircase F1500", 50.0, &stairs, None);
    let (x1, y1) = step(20.0, 0.0, 120.0, 12.0);
    let (x2, y2) = step(x1, y1, 240.0, 12.0);
    let turns = format!("G90 G17 G94\nG1 X20 F2500\nG1 X{x1} Y{y1}\nG1 X{x2} Y{y2}\n");
    check_corner_goals("120° turns F2500", 45.0, &turns, None);
    let arc = "G90 G17 G94\nG1 X15 F2000\nG2 X27 Y0 I6 J0\nG1 X40\n";
    check_corner_goals("line–arc R6–line F2000", 40.0, arc, None);
    let pocket = sq(8.0, 1500.0);
    check_corner_goals(
        "8 mm square G41 F1500",
        50.0,
        &pocket,
        Some(MaterialSide::Right),
    );
}
