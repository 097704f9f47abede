//! Unit tests of `crate::motion::settle`: the run-out of a first-order loop against its
//! closed form, the prediction before the end unchanged, a loop too slow to settle warned of,
//! and an ideal servo that needs no run-out.

use super::*;
use crate::motion::{gcode, predict_program};
use serde_json::json;

fn xyz(kv: f64, kff: f64) -> Machine {
    let ax = json!({"kv": kv, "kff": kff});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

/// A square of 20 mm at F3000 ending at (0, 0).
const SQUARE: &str = "G1 X20 Y0 F3000\nG1 X20 Y20\nG1 X0 Y20\nG1 X0 Y0\n";

#[test]
fn the_run_out_of_a_first_order_loop_settles_as_its_closed_form() {
    let m = xyz(20.0, 0.0);
    let program = gcode::parse(SQUARE).unwrap();
    let plain = predict_program(&m, &program, 1e-3, 1_000_000).unwrap();
    let (p, s) =
        predict_program_settled(&m, &program, &Default::default(), 1e-3, 1_000_000).unwrap();
    let n = plain.commanded.t.len();
    // Up to the command's end the prediction is the plain one, sample for sample.
    for k in 0..3 {
        assert_eq!(p.actual[k][..n], plain.actual[k][..]);
        assert_eq!(p.commanded.axes[k][..n], plain.commanded.axes[k][..]);
    }
    assert!(p.commanded.t.len() > n && p.commanded.line.len() == p.commanded.t.len());
    assert_eq!(p.report.contour_error.len(), p.commanded.t.len());
    // After it the command holds the end point and the lag e decays as e·exp(−kv t): it falls
    // to 0.1 µm at t = ln(e / 0.1 µm)/kv (one period's rounding).
    let e0 = s.lag_at_command_end_mm;
    let want = (e0 / SETTLE_TOLERANCE_MM).ln() / 20.0;
    println!(
        "kv 20: lag at the command's end {:.1} um, settled after {:.3} s (closed form {want:.3} s)",
        e0 * 1e3,
        s.settle_s
    );
    assert!(s.settled && e0 > 1e-3, "{s:?}");
    assert!((s.settle_s - want).abs() <= 1.5e-3, "{s:?} vs {want}");
    assert!(s.lag_at_last_sample_mm <= SETTLE_TOLERANCE_MM * 3f64.sqrt());
    assert!((s.command_end_s - plain.commanded.t[n - 1]).abs() < 1e-12);
    let last = p.commanded.t.len() - 1;
    assert!((p.commanded.t[last] - s.command_end_s - s.settle_s).abs() < 1e-9);
    assert!(s.warning().is_none());
}

#[test]
fn an_ideal_servo_needs_no_run_out_and_a_slow_one_is_warned_of() {
    let program = gcode::parse(SQUARE).unwrap();
    // kff = 1 with ideal inner loops: the axes are on the command, so nothing is added.
    let plain = predict_program(&xyz(20.0, 1.0), &program, 1e-3, 1_000_000).unwrap();
    let (p, s) = predict_program_settled(
        &xyz(20.0, 1.0),
        &program,
        &Default::default(),
        1e-3,
        1_000_000,
    )
    .unwrap();
    assert_eq!(p, plain);
    assert!(s.settled && s.settle_s == 0.0, "{s:?}");
    // kv = 0.5 1/s: from a lag of about 50 mm, 0.1 µm takes 26 s, more than the cap.
    let (p, s) = predict_program_settled(
        &xyz(0.5, 0.0),
        &program,
        &Default::default(),
        1e-3,
        1_000_000,
    )
    .unwrap();
    assert!(!s.settled, "{s:?}");
    assert!((s.settle_s - MAX_SETTLE_S).abs() < 2e-3, "{s:?}");
    assert!(s.lag_at_last_sample_mm > SETTLE_TOLERANCE_MM);
    let w = s.warning().unwrap();
    assert!(w.contains("did not settle") && w.contains("10 s"), "{w}");
    assert!((p.commanded.t.last().unwrap() - s.command_end_s - MAX_SETTLE_S).abs() < 2e-3);
}
