//! Unit tests of `crate::motion::predict`.

use super::*;
use crate::motion::kinematics::Kinematics;
use serde_json::json;

fn xyz_machine(kv: [f64; 3], kff: f64) -> Machine {
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {
            "X": {"kv": kv[0], "kff": kff}, "Y": {"kv": kv[1], "kff": kff}, "Z": {"kv": kv[2], "kff": kff}}}))
        .unwrap()
}

/// Three full circles of radius 10 mm at 100 mm/s (ω = 10 rad/s), CCW or CW.
fn circles(ccw: bool, feed_mm_min: f64) -> String {
    let g = if ccw { "G3" } else { "G2" };
    format!(
        "G0 X10 Y0\nG1 F{feed_mm_min}\n{g} X10 Y0 I-10 J0\n{g} X10 Y0 I-10 J0\n{g} X10 Y0 I-10 J0\n"
    )
}

/// Sample indices of the second circle (source line 4), in steady state.
fn middle(p: &ContourPrediction) -> Vec<usize> {
    (0..p.commanded.line.len())
        .filter(|&i| p.commanded.line[i] == 4)
        .collect()
}

/// Seed-free closed form: a first-order loop (kv only) follows a circle of radius r at
/// ω on a concentric circle of radius r/√(1+(ω/kv)²), so the contour error is
/// r(1 − 1/√(1+(ω/kv)²)).
#[test]
fn circle_first_order_loop_matches_closed_form() {
    let p = predict_contour_error(
        &xyz_machine([30.0; 3], 0.0),
        &circles(true, 6000.0),
        1e-3,
        1_000_000,
    )
    .unwrap();
    let idx = middle(&p);
    assert!(idx.len() > 600, "{}", idx.len());
    // The middle circle runs at the programmed feed (look-ahead through tangent joints).
    let (x, y) = (&p.commanded.axes[0], &p.commanded.axes[1]);
    for w in idx.windows(2) {
        let v = (x[w[1]] - x[w[0]]).hypot(y[w[1]] - y[w[0]]) / 1e-3;
        assert!((v - 100.0).abs() < 0.01, "speed {v}");
    }
    let (r, w, kv): (f64, f64, f64) = (10.0, 10.0, 30.0);
    let expect = r * (1.0 - 1.0 / (1.0 + (w / kv).powi(2)).sqrt());
    let mean = idx.iter().map(|&i| p.report.contour_error[i]).sum::<f64>() / idx.len() as f64;
    let (lo, hi) = idx.iter().fold((f64::MAX, 0.0f64), |(l, h), &i| {
        (
            l.min(p.report.contour_error[i]),
            h.max(p.report.contour_error[i]),
        )
    });
    println!(
        "radial error: ours mean {mean:.6} mm (min {lo:.6}, max {hi:.6}), closed form {expect:.6} mm"
    );
    assert!((lo - expect).abs() < 0.01 * expect && (hi - expect).abs() < 0.01 * expect);
}

#[test]
fn full_feed_forward_with_ideal_inner_loops_is_exact() {
    let p = predict_contour_error(
        &xyz_machine([30.0, 20.0, 25.0], 1.0),
        &circles(true, 6000.0),
        1e-3,
        1_000_000,
    )
    .unwrap();
    println!("kff=1 max contour error {:.3e} mm", p.report.max);
    assert!(p.report.max < 1e-9, "{}", p.report.max);
    assert!(p.report.tracking_max.iter().all(|e| *e < 1e-9));
}

/// Principal-axis angle (deg, in (−90, 90]) of a point set's covariance.
fn major_axis_deg(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for (x, y) in xs.iter().zip(ys) {
        sxx += (x - mx) * (x - mx);
        syy += (y - my) * (y - my);
        sxy += (x - mx) * (y - my);
    }
    0.5 * (2.0 * sxy).atan2(sxx - syy).to_degrees()
}

/// Gain mismatch kv_x ≠ kv_y turns the circle into an ellipse at ±45° that flips with the
/// direction. Closed form: x = r g_x cos(θ−φ_x), y = ±r g_y sin(θ−φ_y) with
/// g = 1/√(1+(ω/kv)²), φ = atan(ω/kv); covariance S_xy = ±r² g_x g_y sin(φ_x−φ_y)/2;
/// for a small mismatch the major axis is at ½·atan2(∓1, ω/kv), i.e. ±45° when ω ≪ kv.
#[test]
fn servo_mismatch_gives_45_degree_ellipse_flipping_with_direction() {
    // 20 mm/s on r = 10 mm: ω = 2 rad/s ≪ kv.
    let (kx, ky, w, r): (f64, f64, f64, f64) = (30.0, 25.0, 2.0, 10.0);
    let (gx, gy) = (
        1.0 / (1.0 + (w / kx).powi(2)).sqrt(),
        1.0 / (1.0 + (w / ky).powi(2)).sqrt(),
    );
    let (px, py) = ((w / kx).atan(), (w / ky).atan());
    let mut got = Vec::new();
    for ccw in [true, false] {
        let p = predict_contour_error(
            &xyz_machine([kx, ky, 30.0], 0.0),
            &circles(ccw, 1200.0),
            1e-3,
            1_000_000,
        )
        .unwrap();
        let idx = middle(&p);
        let xs: Vec<f64> = idx.iter().map(|&i| p.actual[0][i]).collect();
        let ys: Vec<f64> = idx.iter().map(|&i| p.actual[1][i]).collect();
        let ours = major_axis_deg(&xs, &ys);
        let sign = if ccw { 1.0 } else { -1.0 };
        let sxx = r * r * gx * gx / 2.0;
        let syy = r * r * gy * gy / 2.0;
        let sxy = sign * r * r * gx * gy * (px - py).sin() / 2.0;
        let closed = 0.5 * (2.0 * sxy).atan2(sxx - syy).to_degrees();
        println!(
            "{}: ellipse major axis ours {ours:.2}°, closed form {closed:.2}°",
            if ccw { "CCW" } else { "CW" }
        );
        assert!((ours - closed).abs() < 1.0);
        got.push(ours);
    }
    assert!(got[0] < -40.0 && got[0] > -50.0, "{got:?}");
    assert!(got[1] > 40.0 && got[1] < 50.0, "{got:?}");
}

fn five_axis(kff: f64, kv: f64) -> Machine {
    let ax = json!({"kv": kv, "kff": kff});
    Machine::from_json(&json!({"kinematics": "xyzac_table",
            "geometry": {"a_axis_origin": [0.0, 0.0, -150.0], "c_axis_origin": [5.0, -3.0, -100.0], "tool_length": 100.0},
            "axes": {"X": ax, "Y": ax, "Z": ax, "A": ax, "C": ax}}))
        .unwrap()
}

fn point_segment_distance(p: &[f64; 3], a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let d: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
    let r: [f64; 3] = std::array::from_fn(|k| p[k] - a[k]);
    let dd: f64 = d.iter().map(|v| v * v).sum();
    let f = (r.iter().zip(&d).map(|(x, y)| x * y).sum::<f64>() / dd).clamp(0.0, 1.0);
    let q: [f64; 3] = std::array::from_fn(|k| a[k] + f * d[k]);
    crate::motion::program::dist3(p, &q)
}

/// Worst distance of the tool tip (forward kinematics of `cols`) to the workpiece line
/// a→b over the samples of source line `line`, and to a circle of radius `r` about
/// `c` (z = c[2]) over the samples of `arc_line`.
fn tip_deviation(
    p: &ContourPrediction,
    kin: &Kinematics,
    cols: &[Vec<f64>],
    line: u32,
    a: [f64; 3],
    b: [f64; 3],
    arc: Option<(u32, [f64; 3], f64)>,
) -> f64 {
    let mut worst = 0.0f64;
    for (i, &l) in p.commanded.line.iter().enumerate() {
        let q: [f64; 5] = std::array::from_fn(|k| cols[k][i]);
        let tip = kin.forward(&q).tip;
        if l == line {
            worst = worst.max(point_segment_distance(&tip, &a, &b));
        }
        if let Some((arc_line, c, r)) = arc
            && l == arc_line
        {
            let radial = (tip[0] - c[0]).hypot(tip[1] - c[1]) - r;
            worst = worst.max(radial.hypot(tip[2] - c[2]));
        }
    }
    worst
}

/// RTCP + an ideal servo (kff = 1, ideal inner loops) keeps the tool tip on the
/// programmed workpiece path (< 0.1 µm), through a line and an arc with big rotations.
/// The same machine-axis end points interpolated without RTCP leave the path by far more
/// (the non-linear error of Zhang & Chen 2025 §2.2), so the check can fail.
#[test]
fn rtcp_with_ideal_servo_keeps_tip_on_programmed_path() {
    let m = five_axis(1.0, 40.0);
    let prog =
        "G43.4 H1\nG1 X0 Y0 Z0 F3000\nG1 X50 Y20 Z-10 A45 C120\nG3 X30 Y40 Z-10 I-20 J0 A10 C200\n";
    let p = predict_contour_error(&m, prog, 1e-3, 1_000_000).unwrap();
    let dev = tip_deviation(
        &p,
        &m.kinematics,
        &p.actual,
        3,
        [0.0, 0.0, 0.0],
        [50.0, 20.0, -10.0],
        Some((4, [30.0, 20.0, -10.0], 20.0)),
    );
    println!(
        "RTCP + ideal servo: tip deviation from programmed path {dev:.3e} mm (limit 1e-4), contour max {:.3e} mm",
        p.report.max
    );
    assert!(dev < 1e-4, "{dev}");
    assert!(p.report.max < 1e-4, "{}", p.report.max);
    // Without RTCP: program the machine axes of the same two end points.
    let q0 = m.kinematics.inverse(&[0.0, 0.0, 0.0], 0.0, 0.0);
    let q1 = m.kinematics.inverse(&[50.0, 20.0, -10.0], 45.0, 120.0);
    let plain = format!(
        "G1 X{} Y{} Z{} F3000\nG1 X{} Y{} Z{} A45 C120\n",
        q0[0], q0[1], q0[2], q1[0], q1[1], q1[2]
    );
    let p2 = predict_contour_error(&m, &plain, 1e-3, 1_000_000).unwrap();
    let dev2 = tip_deviation(
        &p2,
        &m.kinematics,
        &p2.actual,
        2,
        [0.0, 0.0, 0.0],
        [50.0, 20.0, -10.0],
        None,
    );
    println!("same axes without RTCP: tip deviation {dev2:.3} mm");
    assert!(dev2 > 1.0, "{dev2}");
}

/// A realistic 5-axis servo gives a non-zero contour and orientation error, and the
/// orientation error vanishes with kff = 1.
#[test]
fn five_axis_orientation_error_is_reported() {
    let prog = "G43.4\nG1 X0 Y0 Z0 F3000\nG1 X50 Y20 Z-10 A45 C120\n";
    let lag = predict_contour_error(&five_axis(0.0, 30.0), prog, 1e-3, 1_000_000).unwrap();
    let o = lag.report.orientation_max_deg.unwrap();
    assert!(o > 0.01 && lag.report.max > 1e-3, "{o} {}", lag.report.max);
    let ideal = predict_contour_error(&five_axis(1.0, 30.0), prog, 1e-3, 1_000_000).unwrap();
    assert!(ideal.report.orientation_max_deg.unwrap() < 1e-6);
}

/// One G-code line from a mix of modes, axis words, arcs (R form), RTCP toggles, feeds.
fn gcode_line() -> impl proptest::strategy::Strategy<Value = String> {
    use proptest::prelude::*;
    let word = |r: std::ops::Range<f64>| proptest::option::of(r);
    (
        0usize..9,
        (word(-40.0..40.0), word(-40.0..40.0), word(-20.0..20.0)),
        (word(-60.0..60.0), word(-400.0..400.0)),
        (30.0..90.0f64, word(100.0..6000.0)),
    )
        .prop_map(|(code, (x, y, z), (a, c), (r, f))| {
            let head = [
                "G0", "G1", "G2", "G3", "G43.4 G1", "G49 G1", "G91 G1", "G90 G1", "G4 P20",
            ][code];
            if code == 8 {
                return head.to_string();
            }
            let mut line = head.to_string();
            for (l, v) in [("X", x), ("Y", y), ("Z", z), ("A", a), ("C", c)] {
                if let Some(v) = v {
                    line += &format!(" {l}{v:.3}");
                }
            }
            if code == 2 || code == 3 {
                line += &format!(" R{r:.3}");
            }
            if let Some(f) = f {
                line += &format!(" F{f:.0}");
            }
            line
        })
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(100))]
    /// The whole pipeline never panics on random programs: an answer with finite numbers
    /// of equal lengths, or a typed error.
    #[test]
    fn pipeline_never_panics(lines in proptest::collection::vec(gcode_line(), 1..8)) {
        let m = five_axis(0.5, 30.0);
        let text = format!("G1 F2000\n{}\n", lines.join("\n"));
        if let Ok(p) = predict_contour_error(&m, &text, 1e-3, 60_000) {
            let n = p.commanded.t.len();
            proptest::prop_assert_eq!(p.report.contour_error.len(), n);
            proptest::prop_assert!(p.actual.iter().all(|c| c.len() == n));
            proptest::prop_assert!(p.report.contour_error.iter().all(|v| v.is_finite()));
            proptest::prop_assert!(p.report.max.is_finite() && p.report.rms.is_finite());
        }
    }
}

/// One piece of a programmed XY path: a line or a circular arc (centre, radius, start
/// angle, signed sweep in rad).
enum Piece {
    Line([f64; 2], [f64; 2]),
    Arc([f64; 2], f64, f64, f64),
}

/// Distance (mm) from `p` to the programmed path, by brute force over its pieces.
fn reference_distance_to_path(path: &[Piece], p: [f64; 2]) -> f64 {
    let d = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    path.iter()
        .map(|piece| match *piece {
            Piece::Line(a, b) => {
                let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
                let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy))
                    .clamp(0.0, 1.0);
                d(p, [a[0] + t * dx, a[1] + t * dy])
            }
            Piece::Arc(c, r, start, sweep) => {
                let at = |th: f64| [c[0] + r * th.cos(), c[1] + r * th.sin()];
                let th = (p[1] - c[1]).atan2(p[0] - c[0]);
                // Is th inside the swept range (either sense)?
                let tau = std::f64::consts::TAU;
                let rel = (th - start).rem_euclid(tau);
                let inside = if sweep >= 0.0 {
                    rel <= sweep
                } else {
                    rel == 0.0 || tau - rel <= -sweep
                };
                let ends = d(p, at(start)).min(d(p, at(start + sweep)));
                if inside {
                    (d(p, c) - r).abs().min(ends)
                } else {
                    ends
                }
            }
        })
        .fold(f64::INFINITY, f64::min)
}

/// Precision issue part 4: at a corner (a rapid turning into an arc, a line into a line
/// at 90°) the contour error is the distance to the whole programmed path near the
/// sample, across the block boundary, to 0.1 µm.
#[test]
fn contour_error_at_corners_is_the_distance_to_the_programmed_path() {
    let pi = std::f64::consts::PI;
    let cases: Vec<(&str, String, Vec<Piece>)> = vec![
        (
            "G0 -> G3, 90 deg",
            "G0 X10 Y0\nG3 X0 Y10 I-10 J0 F3000\n".into(),
            vec![
                Piece::Line([0.0, 0.0], [10.0, 0.0]),
                Piece::Arc([0.0, 0.0], 10.0, 0.0, pi / 2.0),
            ],
        ),
        (
            "G0 -> G2, 90 deg",
            "G0 X10 Y0\nG2 X20 Y0 I5 J0 F3000\n".into(),
            vec![
                Piece::Line([0.0, 0.0], [10.0, 0.0]),
                Piece::Arc([15.0, 0.0], 5.0, pi, -pi),
            ],
        ),
        (
            "G1 -> G1, 90 deg",
            "G1 X10 Y0 F3000\nG1 X10 Y10\n".into(),
            vec![
                Piece::Line([0.0, 0.0], [10.0, 0.0]),
                Piece::Line([10.0, 0.0], [10.0, 10.0]),
            ],
        ),
        (
            "G1 -> G1, 135 deg turn",
            "G1 X10 Y0 F6000\nG1 X0 Y10\n".into(),
            vec![
                Piece::Line([0.0, 0.0], [10.0, 0.0]),
                Piece::Line([10.0, 0.0], [0.0, 10.0]),
            ],
        ),
    ];
    for (kv, kff) in [(30.0, 0.0), (60.0, 0.5)] {
        let m = xyz_machine([kv, kv * 0.8, kv], kff);
        for (name, gcode, path) in &cases {
            let p = predict_contour_error(&m, gcode, 1e-3, 1_000_000).unwrap();
            assert_eq!(p.commanded.corners.len(), 1, "{name}");
            let (x, y) = (&p.actual[0], &p.actual[1]);
            let mut worst: f64 = 0.0;
            for i in 0..x.len() {
                let truth = reference_distance_to_path(path, [x[i], y[i]]);
                worst = worst.max((p.report.contour_error[i] - truth).abs());
            }
            eprintln!(
                "{name}, kv {kv}: max |ours - true distance| = {:.4} µm",
                worst * 1e3
            );
            assert!(
                worst <= 1e-4,
                "{name}, kv {kv}: off the true distance by {worst} mm"
            );
        }
    }
}
