//! Unit tests of `crate::cam::predistort`: circles, a free-form program, a square with sharp
//! corners (the case it cannot help), the axis-limit refusal and the option checks.

use super::*;
use crate::motion::{gcode, interpolate, simulate_machine};
use serde_json::json;

/// The demo machine's cascade (kv 30 1/s, kff 0.6, PI velocity loop, 0.5 ms current loop) on
/// X, Y, Z with the default limits (500 mm/s, 5 m/s², 100 m/s³).
fn machine() -> Machine {
    machine_kv(30.0)
}

/// The demo cascade with position-loop gain `kv` (1/s).
fn machine_kv(kv: f64) -> Machine {
    let ax = json!({"kv": kv, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

fn opts() -> PredistortOptions {
    PredistortOptions {
        period_s: 1e-3,
        max_iterations: 30,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
    }
}

/// Two full CCW circles of radius `r` through (0, 15) with tangent lead-in (from the machine's
/// start at the origin) and lead-out lines of 15 mm, so the circle runs at the programmed feed.
fn circle_program(r: f64, feed: f64) -> String {
    format!(
        "G90 G17 G94\nG1 X0 Y15 F{feed}\nG3 X0 Y15 I{m} J0\nG3 X0 Y15 I{m} J0\nG1 Y30\n",
        m = -r
    )
}

/// A free-form CAM-like program: a G01 polyline of 0.25 mm chords along the smooth curve
/// y = 6 sin(2πx/60) + 1.5 sin(2πx/23) for x in 0..120 mm (smallest radius of curvature
/// 5.6 mm), entered by a 10 mm tangent lead-in
/// from the machine's start at the origin.
fn free_form_program(feed: f64) -> String {
    let tau = std::f64::consts::TAU;
    let f = |x: f64| 6.0 * (tau * x / 60.0).sin() + 1.5 * (tau * x / 23.0).sin();
    let slope = 6.0 * tau / 60.0 + 1.5 * tau / 23.0;
    let n = (1.0 + slope * slope).sqrt();
    let (x0, y0) = (10.0 / n, 10.0 * slope / n);
    let mut p = format!("G90 G17 G94\nG1 X{x0:.4} Y{y0:.4} F{feed}\n");
    for k in 1..=480 {
        let x = k as f64 * 0.25;
        p += &format!("G1 X{:.4} Y{:.4}\n", x0 + x, y0 + f(x));
    }
    p
}

/// Interpolation periods of the returned points, read back as the service would.
fn periods_of(m: &Machine, out: &Predistorted) -> usize {
    let mut text = String::from("G90 G94\n");
    for p in &out.points {
        text += &format!(
            "G1 X{:.4} Y{:.4} Z{:.4} F{:.3}\n",
            p.axes[0], p.axes[1], p.axes[2], p.feed_mm_min
        );
    }
    let prog = gcode::parse(&text).unwrap();
    interpolate(&prog, m, 1e-3, MAX_PERIODS).unwrap().t.len()
}

/// Runs `text`, prints the figures beside the goals, checks the feeds and the duration, and
/// returns the result.
fn run_and_report(name: &str, text: &str) -> Predistorted {
    let m = machine();
    let prog = gcode::parse(text).unwrap();
    let out = predistort(&m, &prog, &opts()).unwrap();
    let (o, c) = (out.original, out.compensated);
    println!(
        "{name}: original RMS {:.2} µm max {:.2} µm; ours RMS {:.2} µm max {:.2} µm; \
         ratio RMS {:.3} (goal ≤ 0.1, gate ≤ 0.3), max {:.3} (goal ≤ 0.3); {} iterations, {} points",
        o.rms_mm * 1e3,
        o.max_mm * 1e3,
        c.rms_mm * 1e3,
        c.max_mm * 1e3,
        c.rms_mm / o.rms_mm,
        c.max_mm / o.max_mm,
        out.iterations,
        out.points.len()
    );
    for n in &out.notes {
        println!("  note: {n}");
    }
    // No point slower than its original block's programmed feed.
    for p in &out.points {
        let b = prog.blocks.iter().find(|b| b.line == p.line).unwrap();
        let f = match b.feed {
            gcode::Feed::PerMinute(f) => f,
            gcode::Feed::Rapid => m.rapid_mm_min,
            gcode::Feed::InverseTime(_) => unreachable!(),
        };
        assert!(
            p.feed_mm_min >= f,
            "line {}: {} < {f}",
            p.line,
            p.feed_mm_min
        );
    }
    // The returned program, read back from text, takes no longer than the original.
    let orig_periods = interpolate(&prog, &m, 1e-3, MAX_PERIODS).unwrap().t.len();
    let ours = periods_of(&m, &out);
    println!("  periods: original {orig_periods}, compensated {ours}");
    assert!(ours <= orig_periods + 3, "{ours} > {orig_periods} + 3");
    out
}

/// Re-checks the figure from the text the route would emit: parse, interpolate, simulate and
/// measure against the original path, all through the motion core.
fn recheck_from_text(text: &str, out: &Predistorted) -> (f64, f64) {
    recheck_on(&machine(), text, out)
}

fn recheck_on(m: &Machine, text: &str, out: &Predistorted) -> (f64, f64) {
    let m = m.clone();
    let orig = predict_program(&m, &gcode::parse(text).unwrap(), 1e-3, MAX_PERIODS).unwrap();
    let mut g = String::from("G90 G94\n");
    for p in &out.points {
        g += &format!(
            "G1 X{:.4} Y{:.4} Z{:.4} F{:.3}\n",
            p.axes[0], p.axes[1], p.axes[2], p.feed_mm_min
        );
    }
    let mut cmd = interpolate(&gcode::parse(&g).unwrap(), &m, 1e-3, MAX_PERIODS).unwrap();
    let n = cmd.t.len().max(orig.commanded.t.len());
    let pad = |cols: &mut Vec<Vec<f64>>| {
        for c in cols.iter_mut() {
            let l = *c.last().unwrap();
            c.resize(n, l);
        }
    };
    pad(&mut cmd.axes);
    let actual = simulate_machine(&m, &cmd).unwrap();
    let mut oc = orig.commanded.axes.clone();
    pad(&mut oc);
    let r = contour_error(&m.kinematics, &oc, &actual, &orig.commanded.corners);
    (r.rms, r.max)
}

#[test]
fn circles_meet_the_gate() {
    for (r, feed) in [
        (10.0, 3000.0),
        (25.0, 2000.0),
        (50.0, 1000.0),
        (50.0, 3000.0),
    ] {
        let text = circle_program(r, feed);
        let out = run_and_report(&format!("circle R{r} F{feed}"), &text);
        let (o, c) = (out.original, out.compensated);
        assert!(o.max_mm > 1e-3, "the original must have an error to remove");
        assert!(
            c.rms_mm <= 0.3 * o.rms_mm,
            "RMS {} vs {}",
            c.rms_mm,
            o.rms_mm
        );
        assert!(
            c.max_mm <= 0.3 * o.max_mm,
            "max {} vs {}",
            c.max_mm,
            o.max_mm
        );
        let again = recheck_from_text(&text, &out);
        assert!(
            (again.0 - c.rms_mm).abs() <= 1e-9 && (again.1 - c.max_mm).abs() <= 1e-9,
            "{again:?} vs {c:?}"
        );
    }
}

#[test]
fn free_form_meets_the_gate() {
    let text = free_form_program(2500.0);
    let out = run_and_report("free-form G01 F2500", &text);
    let (o, c) = (out.original, out.compensated);
    assert!(o.max_mm > 1e-3);
    assert!(
        c.rms_mm <= 0.3 * o.rms_mm,
        "RMS {} vs {}",
        c.rms_mm,
        o.rms_mm
    );
    assert!(
        c.max_mm <= 0.3 * o.max_mm,
        "max {} vs {}",
        c.max_mm,
        o.max_mm
    );
    let again = recheck_from_text(&text, &out);
    assert!((again.0 - c.rms_mm).abs() <= 1e-9, "{again:?} vs {c:?}");
}

#[test]
fn options_rotary_machines_and_dwells_are_refused() {
    let m = machine();
    let prog = gcode::parse(&circle_program(10.0, 1000.0)).unwrap();
    let bad = PredistortOptions {
        period_s: 0.0,
        max_iterations: 3,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
    };
    assert!(matches!(
        predistort(&m, &prog, &bad),
        Err(Error::Option {
            field: "period_s",
            ..
        })
    ));
    let bad = PredistortOptions {
        period_s: 1e-3,
        max_iterations: 1000,
        max_duration_ratio: DEFAULT_MAX_DURATION_RATIO,
    };
    assert!(matches!(
        predistort(&m, &prog, &bad),
        Err(Error::Option {
            field: "max_iterations",
            ..
        })
    ));
    for ratio in [0.99, 2.5, f64::NAN] {
        let bad = PredistortOptions {
            max_duration_ratio: ratio,
            ..opts()
        };
        assert!(matches!(
            predistort(&m, &prog, &bad),
            Err(Error::Option {
                field: "max_duration_ratio",
                ..
            })
        ));
    }
    let dwell = gcode::parse("G0 X1\nG4 P0.5\nG1 X2 F100\n").unwrap();
    let e = predistort(&m, &dwell, &opts()).unwrap_err();
    assert!(e.to_string().contains("line 2"), "{e}");
}

#[test]
fn correction_spreads_and_fills() {
    let sigma = [0.0, 1.0, 2.0, 3.0];
    let feet = vec![(0.5, [2.0, 0.0, 0.0]), (3.0, [0.0, 4.0, 0.0])];
    let c = correction(&sigma, &feet);
    assert_eq!(c[0], [2.0, 0.0, 0.0]);
    assert_eq!(c[1], [2.0, 0.0, 0.0]);
    // Point 2 got no weight: halfway between its neighbours.
    assert_eq!(c[2], [1.0, 2.0, 0.0]);
    assert_eq!(c[3], [0.0, 4.0, 0.0]);
}

/// Oracle: the foot-point distances on the reference polyline agree with the motion core's
/// contour error (spline, windowed search) on the original run.
#[test]
fn feet_agree_with_contour_error() {
    let m = machine();
    for text in [circle_program(10.0, 3000.0), free_form_program(2500.0)] {
        let prog = gcode::parse(&text).unwrap();
        let orig = predict_program(&m, &prog, 1e-3, MAX_PERIODS).unwrap();
        let r = Reference::new(&m, &prog, &orig.commanded);
        let tips: Vec<[f64; 3]> = (0..orig.actual[0].len())
            .map(|i| [orig.actual[0][i], orig.actual[1][i], orig.actual[2][i]])
            .collect();
        let feet = r.feet(&tips);
        let worst = feet
            .iter()
            .zip(&orig.report.contour_error)
            .map(|((_, e), c)| ((e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt() - c).abs())
            .fold(0.0, f64::max);
        println!(
            "largest difference foot distance vs contour_error: {:.3} µm",
            worst * 1e3
        );
        assert!(worst < 0.5e-3, "{worst}");
    }
}

/// The plain scan [`Reference::feet`] makes without its bounding spheres (the search of its
/// docs, every segment of the window looked at).
fn feet_plain(r: &Reference, actual: &[[f64; 3]]) -> Vec<(f64, [f64; 3])> {
    let nseg = r.knots.len() - 1;
    let mut prev = 0usize;
    let mut out = Vec::new();
    for a in actual {
        let (d0, f0) = reference::chord_distance(&r.knots[prev], &r.knots[prev + 1], a);
        let s0 = r.cum[prev] + f0 * (r.cum[prev + 1] - r.cum[prev]);
        let reach = 8.0 * d0 + 1e-9;
        let mut best = (d0, prev, f0);
        let mut j = prev;
        while j > 0 && r.cum[j] >= s0 - reach {
            j -= 1;
            let (d, f) = reference::chord_distance(&r.knots[j], &r.knots[j + 1], a);
            if d < best.0 {
                best = (d, j, f);
            }
        }
        let mut j = prev + 1;
        while j < nseg && r.cum[j] <= s0 + reach {
            let (d, f) = reference::chord_distance(&r.knots[j], &r.knots[j + 1], a);
            if d < best.0 {
                best = (d, j, f);
            }
            j += 1;
        }
        let (_, j, f) = best;
        prev = j;
        let (p0, p1) = (r.knots[j], r.knots[j + 1]);
        let foot: [f64; 3] = std::array::from_fn(|d| p0[d] + f * (p1[d] - p0[d]));
        let s = r.cum[j] + f * (r.cum[j + 1] - r.cum[j]);
        out.push((s, std::array::from_fn(|d| a[d] - foot[d])));
    }
    out
}

/// The bounding spheres only speed the foot search up: on a program with rapids, a peck
/// cycle that retraces its own path, sharp corners and arcs (the simulated tips, and the
/// tips pushed up to 3 mm off the path), the feet are those of the plain scan, bit for bit.
#[test]
fn pruned_foot_search_finds_the_plain_scans_feet() {
    let m = machine();
    let text = "G90 G17 G94\nG0 X5 Y5 Z5\nG1 Z-1 F600\nG1 X25 F2000\nG3 X35 Y15 R10\nG1 Y30\n\
                G1 X5 Y31\nG0 Z5\nG99 G83 X20 Y20 Z-12 R2 Q3 F200\nX30\nG80\nG0 X0 Y0 Z10\n";
    let (prog, _) = gcode::parse_with(text, &crate::motion::ReadOptions::default()).unwrap();
    let orig = predict_program(&m, &prog, 1e-3, MAX_PERIODS).unwrap();
    let r = Reference::new(&m, &prog, &orig.commanded);
    let mut tips: Vec<[f64; 3]> = (0..orig.actual[0].len())
        .map(|i| [orig.actual[0][i], orig.actual[1][i], orig.actual[2][i]])
        .collect();
    let plain = feet_plain(&r, &tips);
    assert_eq!(r.feet(&tips), plain);
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for t in tips.iter_mut() {
        let scale = if next() > 0.3 { 6.0 } else { 0.05 };
        *t = std::array::from_fn(|d| t[d] + scale * next());
    }
    let plain = feet_plain(&r, &tips);
    println!("{} tips, {} knots", tips.len(), r.knots.len());
    assert_eq!(r.feet(&tips), plain);
}

/// A retraced path (up to a clearance plane, back down the same line, plunge, then across):
/// without a hint the foot slides back down the pass the tool has left and stays there, so the
/// tool moving off across reads millimetres from the path; with the command's arc position as
/// the hint the foot keeps to the pass ahead and the tool stays within its real contour error.
#[test]
fn hinted_feet_keep_to_the_pass_ahead_where_the_path_retraces_itself() {
    let m = machine();
    let text = "G90 G17 G94\nG0 X20 Y10\nG0 Z30\nG0 Z5\nG1 Z-2 F600\nG1 X60 Y20 F1500\n";
    let (prog, _) = gcode::parse_with(text, &crate::motion::ReadOptions::default()).unwrap();
    let orig = predict_program(&m, &prog, 1e-3, MAX_PERIODS).unwrap();
    let r = Reference::new(&m, &prog, &orig.commanded);
    let tips: Vec<[f64; 3]> = (0..orig.actual[0].len())
        .map(|i| [orig.actual[0][i], orig.actual[1][i], orig.actual[2][i]])
        .collect();
    let cmd: Vec<[f64; 3]> = (0..orig.commanded.axes[0].len())
        .map(|i| {
            let a = &orig.commanded.axes;
            [a[0][i], a[1][i], a[2][i]]
        })
        .collect();
    // The command's own arc position: the length of its path so far (its samples are the
    // knots of the reference).
    let mut run = 0.0;
    let hint: Vec<f64> = (0..cmd.len())
        .map(|i| {
            if i > 0 {
                run += run::norm(run::sub(cmd[i], cmd[i - 1]));
            }
            run
        })
        .collect();
    let worst = |feet: &[(f64, [f64; 3])]| {
        feet.iter()
            .map(|(_, e)| (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
            .fold(0.0, f64::max)
    };
    let plain = worst(&r.feet(&tips));
    let hinted = worst(&r.feet_hinted(&tips, Some(&hint)));
    println!(
        "largest foot distance: {:.1} µm plain, {:.1} µm hinted; motion core's contour error {:.1} µm",
        plain * 1e3,
        hinted * 1e3,
        orig.report.max * 1e3
    );
    assert!(
        plain > 1.0,
        "the plain search no longer slides back: {plain} mm"
    );
    assert!(hinted <= orig.report.max + 1e-3, "{hinted} mm");
}

/// A 90° outside corner from +X to +Y (F 2000, junction speed 5 mm/s, source line 2) at
/// point `k` and path parameter `sigma` (mm), judged on `lo..hi` (mm), with braking lead cap
/// `cap_lead_mm`: the corner of the stages' unit tests.
pub(super) fn right_angle_spot(
    k: usize,
    sigma: f64,
    (lo, hi): (f64, f64),
    cap_lead_mm: f64,
) -> corners::CornerSpot {
    corners::CornerSpot {
        k,
        d_in: [1.0, 0.0, 0.0],
        d_out: [0.0, 1.0, 0.0],
        inside: [-1.0 / 2f64.sqrt(), 1.0 / 2f64.sqrt(), 0.0],
        outside: true,
        turn_rad: std::f64::consts::FRAC_PI_2,
        cap_mm: 0.5,
        cap_lead_mm,
        feed_mm_min: 2000.0,
        sigma,
        lo,
        hi,
        v_junction: 5.0,
        line: 2,
    }
}
