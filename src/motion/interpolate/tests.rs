//! Unit tests of `crate::motion::interpolate`.

use super::*;
use crate::motion::gcode::parse;
use serde_json::json;

fn xyz(limits: serde_json::Value) -> Machine {
    let mut ax = json!({"kv": 30});
    for (k, v) in limits.as_object().unwrap() {
        ax[k] = v.clone();
    }
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

fn run(m: &Machine, text: &str) -> Trajectory {
    interpolate(&parse(text).unwrap(), m, 1e-3, 10_000_000).unwrap()
}

/// Max |first, second, third difference| per axis (velocity, acceleration, jerk).
fn derivatives(t: &Trajectory, skip: &dyn Fn(usize) -> bool) -> (f64, f64, f64) {
    let h = t.period_s;
    let (mut v, mut a, mut j) = (0.0f64, 0.0f64, 0.0f64);
    for col in &t.axes {
        for k in 3..col.len() {
            if skip(k) {
                continue;
            }
            v = v.max(((col[k] - col[k - 1]) / h).abs());
            a = a.max(((col[k] - 2.0 * col[k - 1] + col[k - 2]) / (h * h)).abs());
            j = j.max(
                ((col[k] - 3.0 * col[k - 1] + 3.0 * col[k - 2] - col[k - 3]) / (h * h * h)).abs(),
            );
        }
    }
    (v, a, j)
}

#[test]
fn line_respects_axis_limits_and_reaches_the_feed() {
    let m = xyz(json!({"max_vel": 200.0, "max_accel": 2000.0, "max_jerk": 40000.0}));
    // Programmed 300 mm/s along X: capped to 200 mm/s by max_vel.
    let t = run(&m, "G1 X400 F18000");
    let (v, a, j) = derivatives(&t, &|_| false);
    assert!((v - 200.0).abs() < 1e-6, "v {v}");
    assert!(a <= 2000.0 * 1.001, "a {a}");
    assert!(j <= 40000.0 * 1.05, "j {j}");
    assert_eq!(*t.axes[0].last().unwrap(), 400.0);
    // Duration: 400/200 s cruise-equivalent plus one ramp (accel) time: dv/a + a/j.
    let expect = 400.0 / 200.0 + 200.0 / 2000.0 + 2000.0 / 40000.0;
    let got = t.t.last().unwrap();
    assert!((got - expect).abs() < 2e-3, "{got} vs {expect}");
}

#[test]
fn look_ahead_keeps_speed_through_tangent_junctions_and_stops_at_corners() {
    let m = xyz(json!({}));
    // 36 arcs of 10° forming a circle: tangent junctions, speed must not dip.
    let mut prog = String::from("G0 X10 Y0\nG1 F3000\n");
    for k in 1..=36 {
        let th = (k as f64 * 10.0f64).to_radians();
        let (x0, y0) = (
            10.0 * ((k - 1) as f64 * 10.0f64).to_radians().cos(),
            10.0 * ((k - 1) as f64 * 10.0f64).to_radians().sin(),
        );
        prog += &format!(
            "G3 X{:.9} Y{:.9} I{:.9} J{:.9}\n",
            10.0 * th.cos(),
            10.0 * th.sin(),
            -x0,
            -y0
        );
    }
    let t = run(&m, &prog);
    let speeds: Vec<f64> = (1..t.t.len())
        .filter(|&k| t.line[k] >= 12 && t.line[k] <= 30)
        .map(|k| (t.axes[0][k] - t.axes[0][k - 1]).hypot(t.axes[1][k] - t.axes[1][k - 1]) / 1e-3)
        .collect();
    let min = speeds.iter().cloned().fold(f64::MAX, f64::min);
    assert!((min - 50.0).abs() < 1e-3, "speed dipped to {min}");
    // A 90° corner between two lines: the speed at the corner is bounded by
    // max_accel·period/|Δ(dq/ds)| per axis = 5000·1e-3/1 = 5 mm/s.
    let t = run(&m, "G1 X50 F6000\nG1 Y50");
    let corner = t.line.iter().position(|&l| l == 2).unwrap();
    let v = (t.axes[0][corner] - t.axes[0][corner - 1])
        .hypot(t.axes[1][corner] - t.axes[1][corner - 1])
        / 1e-3;
    assert!(v <= 5.0 + 1e-9, "corner speed {v}");
    let (_, a, _) = derivatives(&t, &|_| false);
    assert!(a <= 5000.0 * 2.01, "a {a}");
}

/// Zhang & Chen 2025 eqs. 4–7: with RTCP the programmed F is the tool-tip speed; without RTCP
/// it is the speed in the extended displacement √(ΔX²+…+ΔA²+ΔC²) (rotary terms in radians).
#[test]
fn feed_distribution_follows_seed_equations() {
    let ax = json!({"kv": 30, "max_vel": 1e6, "max_accel": 1e7, "max_jerk": 1e10});
    let m = Machine::from_json(&json!({"kinematics": "xyzac_table",
            "geometry": {"a_axis_origin": [0, 0, -50], "tool_length": 100},
            "axes": {"X": ax, "Y": ax, "Z": ax, "A": ax, "C": ax}}))
    .unwrap();
    // RTCP on: tip speed = F/60 = 20 mm/s in mid-block.
    let t = run(&m, "G43.4\nG1 X0 Y0 Z0 F1200\nG1 X100 Y0 Z0 A30 C90\n");
    let k = t.line.iter().position(|&l| l == 3).unwrap() + (100.0 / 20.0 / 2.0 / 1e-3) as usize;
    let tip = |k: usize| {
        m.kinematics
            .forward(&std::array::from_fn(|i| t.axes[i][k]))
            .tip
    };
    let v = crate::motion::program::dist3(&tip(k), &tip(k - 1)) / 1e-3;
    assert!((v - 20.0).abs() < 1e-3, "tip speed {v}");
    // RTCP off: 100 mm in X with 90° of C: ΔL = √(100² + (π/2)²); block time ΔL/F.
    let t = run(&m, "G1 X100 C90 F1200\n");
    let dl = (100.0f64.powi(2) + std::f64::consts::FRAC_PI_2.powi(2)).sqrt();
    let k = t.t.len() / 2;
    let vx = (t.axes[0][k] - t.axes[0][k - 1]) / 1e-3;
    let vc = (t.axes[4][k] - t.axes[4][k - 1]) / 1e-3;
    assert!((vx - 100.0 / dl * 20.0).abs() < 1e-6, "vx {vx}");
    assert!((vc - 90.0 / dl * 20.0).abs() < 1e-6, "vc {vc}");
    // G93: the block takes 1/F min: F2 → 30 s (plus the tiny ramps here).
    let t = run(&m, "G93 G1 X10 F2\n");
    assert!(
        (t.t.last().unwrap() - 30.0).abs() < 0.01,
        "{}",
        t.t.last().unwrap()
    );
}

#[test]
fn bad_inputs_are_typed_errors() {
    let m = xyz(json!({}));
    let e = interpolate(&parse("G1 X1 F100\nG1 A10").unwrap(), &m, 1e-3, 1000).unwrap_err();
    assert!(matches!(e, Error::Gcode { line: 2, .. }), "{e:?}");
    let e = interpolate(&parse("G1 X1000 F10").unwrap(), &m, 1e-3, 1000).unwrap_err();
    assert!(
        matches!(e, Error::TooManyPeriods { limit: 1000, .. }),
        "{e:?}"
    );
    let e = interpolate(&parse("G1 X1 F10").unwrap(), &m, 0.0, 1000).unwrap_err();
    assert!(matches!(e, Error::InvalidParameter { .. }), "{e:?}");
    let e = interpolate(&parse("G1 F10\n(nothing)").unwrap(), &m, 1e-3, 1000).unwrap_err();
    assert_eq!(e, Error::EmptyProgram);
}

#[test]
fn dwell_holds_position() {
    let m = xyz(json!({}));
    let t = run(&m, "G1 X10 F600\nG4 X0.5\nG1 X20");
    let dwell: Vec<usize> = (0..t.t.len()).filter(|&k| t.line[k] == 2).collect();
    assert!(dwell.len() >= 499 && dwell.len() <= 501, "{}", dwell.len());
    assert!(dwell.iter().all(|&k| t.axes[0][k] == 10.0));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
    /// Whatever parses also interpolates without panicking (error or trajectory).
    #[test]
    fn random_programs_never_panic(
        s in "(G[0-3] |G9[01] |G1[789] |G43.4 |G49 )?([XYZAC][-]?[0-9]{1,3}(\\.[0-9]{1,3})? ){1,4}([IJKR][-]?[0-9]{1,2} ){0,2}(F[1-9][0-9]{0,4})?\n{1,8}"
    ) {
        let ax = json!({"kv": 30});
        let m = Machine::from_json(&json!({"kinematics": "xyzac_table",
            "axes": {"X": ax, "Y": ax, "Z": ax, "A": ax, "C": ax}})).unwrap();
        if let Ok(p) = parse(&format!("G1 F1000\n{s}"))
            && let Ok(t) = interpolate(&p, &m, 1e-3, 200_000)
        {
            proptest::prop_assert!(t.axes.iter().flatten().all(|v| v.is_finite()));
        }
    }
}

/// A CAM post's chords of a small radius: a circle R 0.5 mm as 0.01 mm chords (a 1.15° turn
/// at each junction) at F 6000. Each junction alone would allow 250 mm/s; with eight of
/// them inside one period their velocity steps add up. The direction change is taken over
/// the path of one period, so the circle runs at about √(max_accel·R) = 50 mm/s and the
/// commanded acceleration stays at the axis limit (before: 100 mm/s, 20,000 mm/s², 4×).
#[test]
fn short_chords_of_a_small_radius_keep_the_acceleration_limit() {
    let m = xyz(json!({"max_vel": 500.0, "max_accel": 5000.0, "max_jerk": 100_000.0}));
    let (r, n) = (0.5f64, 314usize);
    let mut text = String::from("G90 G1 X-5 Y0 F6000\nG1 X0 Y0\n");
    for k in 1..=n {
        let th = std::f64::consts::TAU * k as f64 / n as f64;
        text += &format!("X{:.6} Y{:.6}\n", r * th.sin(), r - r * th.cos());
    }
    text += "G1 X5 Y0\n";
    let t = run(&m, &text);
    let h = t.period_s;
    let (mut a_max, mut v_circle) = (0.0f64, 0.0f64);
    for k in 2..t.t.len() {
        let sec = |c: &Vec<f64>| (c[k] - 2.0 * c[k - 1] + c[k - 2]) / (h * h);
        a_max = a_max.max(sec(&t.axes[0]).abs()).max(sec(&t.axes[1]).abs());
        if t.line[k] > 3 && (t.line[k] as usize) < n {
            let v = (t.axes[0][k] - t.axes[0][k - 1]).hypot(t.axes[1][k] - t.axes[1][k - 1]) / h;
            v_circle = v_circle.max(v);
        }
    }
    let centripetal = (5000.0 * r).sqrt();
    println!(
        "chords of R 0.5 at F 6000: {v_circle:.1} mm/s on the circle (√(A·R) {centripetal:.1}), \
         peak commanded acceleration {a_max:.0} mm/s² (limit 5000)"
    );
    assert!(a_max <= 1.2 * 5000.0, "peak acceleration {a_max} mm/s²");
    assert!(
        v_circle > 0.8 * centripetal && v_circle < 1.1 * centripetal,
        "{v_circle} mm/s"
    );
}

/// A straight line split into collinear pieces is the same line: the look-ahead carries the
/// acceleration across the junctions (`chain_units`), so 1,000 blocks of 20 µm plan exactly
/// as one 20 mm block (before, each block restarted its ramp from zero acceleration: the
/// split line took 1.218 s at 24.7 mm/s peak against 0.446 s at the programmed 50 mm/s).
/// Each sample still carries the line of the block it lies on.
#[test]
fn collinear_pieces_plan_as_the_unsplit_line() {
    let m = xyz(json!({"max_vel": 500.0, "max_accel": 5000.0, "max_jerk": 100_000.0}));
    let one = run(&m, "G90 G1 X20 F3000\n");
    let mut text = String::from("G90 F3000\n");
    for k in 1..=1000 {
        text += &format!("G1 X{:.3}\n", k as f64 * 0.02);
    }
    let split = run(&m, &text);
    assert_eq!(split.t.len(), one.t.len(), "periods");
    let worst = one.axes[0]
        .iter()
        .zip(&split.axes[0])
        .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
    assert!(
        worst < 1e-9,
        "split line departs from the line by {worst} mm"
    );
    assert!(split.corners.is_empty());
    for (k, x) in split.axes[0].iter().enumerate().skip(1) {
        // Block on line n (n ≥ 2) ends at X = 0.02·(n − 1).
        let line = split.line[k] as f64;
        let (lo, hi) = (0.02 * (line - 2.0), 0.02 * (line - 1.0));
        assert!(
            *x >= lo - 1e-9 && *x <= hi + 1e-9,
            "sample {k} at X {x} on line {line}"
        );
    }
}

/// A CAM post's chords of a large radius run as the arc would: a circle R 25 mm as 0.1 mm
/// chords (0.23° turns, each junction allowing far more than the feed) at F 3000 from rest
/// reaches the feed, and the commanded acceleration and jerk stay within the axis limits.
/// Before the chords were planned as one run, each 0.1 mm block started and ended its speed
/// ramp at zero acceleration, so the tool crept up to the feed over many blocks.
#[test]
fn chords_of_a_large_radius_carry_the_acceleration() {
    let m = xyz(json!({"max_vel": 500.0, "max_accel": 5000.0, "max_jerk": 100_000.0}));
    let (r, n) = (25.0f64, 1571usize);
    let mut text = String::from("G90 F3000\n");
    for k in 1..=n {
        let th = std::f64::consts::TAU * k as f64 / n as f64;
        text += &format!("G1 X{:.6} Y{:.6}\n", r * th.sin(), r - r * th.cos());
    }
    let t = run(&m, &text);
    let (v, a, _) = derivatives(&t, &|_| false);
    // Jerk along the path (the chords' direction steps make the axes' third differences
    // spike at every junction, with or without the look-ahead): third difference of the
    // path length covered.
    let h = t.period_s;
    let speed: Vec<f64> = (1..t.t.len())
        .map(|k| (t.axes[0][k] - t.axes[0][k - 1]).hypot(t.axes[1][k] - t.axes[1][k - 1]) / h)
        .collect();
    let j = speed.windows(3).fold(0.0f64, |m, w| {
        m.max((w[2] - 2.0 * w[1] + w[0]).abs() / (h * h))
    });
    let duration = t.t.last().unwrap();
    println!(
        "R 25 as 0.1 mm chords at F 3000: peak axis speed {v:.1} mm/s, acceleration {a:.0} mm/s² \
         (limit 5000), path jerk {j:.0} mm/s³ (limit 100000), {duration:.3} s (path at the feed {:.3} s)",
        std::f64::consts::TAU * r / 50.0
    );
    assert!(v > 49.0 && v <= 50.0 + 1e-6, "peak axis speed {v} mm/s");
    assert!(a <= 5000.0 * 1.05, "acceleration {a} mm/s²");
    assert!(j <= 100_000.0 * 1.05, "path jerk {j} mm/s³");
    assert!(
        *duration < 1.1 * std::f64::consts::TAU * r / 50.0,
        "{duration} s"
    );
}

/// Blocks of different feeds chained by the look-ahead keep each block's own feed: a 20 mm
/// line whose first half is 0.02 mm blocks at F 6000 and second half 0.02 mm blocks at
/// F 3000 runs no block above its feed and plans as the same line in two blocks (within a
/// few periods), the fast half slowing down before the slow half starts.
#[test]
fn chained_blocks_keep_their_own_feeds() {
    let m = xyz(json!({"max_vel": 500.0, "max_accel": 5000.0, "max_jerk": 100_000.0}));
    let two = run(&m, "G90 G1 X10 F6000\nG1 X20 F3000\n");
    let mut text = String::from("G90\n");
    for k in 1..=1000 {
        let f = if k <= 500 { 6000 } else { 3000 };
        text += &format!("G1 X{:.3} F{f}\n", k as f64 * 0.02);
    }
    let t = run(&m, &text);
    let h = t.period_s;
    for k in 1..t.t.len() {
        let v = (t.axes[0][k] - t.axes[0][k - 1]) / h;
        let cap = if t.line[k] as usize <= 501 {
            100.0
        } else {
            50.0
        };
        // A sample's step may straddle the junction into the slower block.
        let cap = if t.axes[0][k - 1] < 10.0 {
            100.0f64.max(cap)
        } else {
            cap
        };
        assert!(
            v <= cap * (1.0 + 1e-9),
            "sample {k}: {v} mm/s on line {}",
            t.line[k]
        );
    }
    let (a, b) = (t.t.len() as i64, two.t.len() as i64);
    println!("F 6000 / F 3000 halves: {a} periods in 0.02 mm blocks, {b} in two blocks");
    assert!((a - b).abs() <= 3, "{a} periods against {b}");
}
