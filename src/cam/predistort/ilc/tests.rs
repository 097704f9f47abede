//! Laws of the corner-window ILC's residuals: their sum of squares is the window's
//! distance-weighted squared error, and a shift of the run in time leaves them unchanged.

use super::*;
use crate::cam::predistort::measure::path_weights;
use crate::motion::{Machine, gcode, predict_program};
use serde_json::json;

fn machine() -> Machine {
    let ax = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

/// The original run of a 90° corner at (10, 0) as an [`Eval`] against its own reference, and
/// the corner's spot with its window 3 mm either side (an outside corner).
fn corner_run(pad_periods: usize) -> (Reference, Eval, CornerSpot) {
    let m = machine();
    let prog = gcode::parse("G90 G17 G94\nG1 X10 F2000\nG1 Y10\n").unwrap();
    let orig = predict_program(&m, &prog, 1e-3, 100_000).unwrap();
    let reference = Reference::new(&m, &prog, &orig.commanded);
    // Standing still at the start for `pad_periods` shifts the whole run in time.
    let actual: Vec<Vec<f64>> = orig
        .actual
        .iter()
        .map(|c| {
            let mut v = vec![c[0]; pad_periods];
            v.extend_from_slice(c);
            v
        })
        .collect();
    let tips = tips_of(&actual);
    let feet = reference.feet(&tips);
    let eval = Eval {
        feeds: vec![],
        line: vec![],
        periods: actual[0].len(),
        actual,
        feet,
        rms: 0.0,
        max: 0.0,
    };
    let spot = crate::cam::predistort::tests::right_angle_spot(0, 10.0, (7.0, 13.0), 2.0);
    (reference, eval, spot)
}

/// Σ r² over the grid (the gouge terms are zero at an outside corner) against the
/// trapezoidal `Σ wᵢ|eᵢ|²` of the periods whose feet lie in the window.
#[test]
fn residuals_sum_to_the_distance_weighted_squared_error() {
    let (reference, e, spot) = corner_run(0);
    let tips = tips_of(&e.actual);
    let r = residuals(&reference, &spot, &e, &tips);
    assert_eq!(r.len(), 4 * GRID);
    let grid: f64 = r.iter().map(|v| v * v).sum();
    let w = path_weights(&tips);
    let direct: f64 = e
        .feet
        .iter()
        .zip(&w)
        .filter(|((s, _), _)| (spot.lo..=spot.hi).contains(s))
        .map(|((_, v), w)| w * v.iter().map(|x| x * x).sum::<f64>())
        .sum();
    println!("grid {grid:.4e} mm³, per period {direct:.4e} mm³");
    assert!(direct > 1e-7, "the corner must have an error to measure");
    assert!(
        (grid - direct).abs() <= 0.03 * direct,
        "grid {grid} vs per period {direct}"
    );
}

/// The same path reached later (the tool standing still first) gives the same residuals:
/// they follow the tool's path length, not the periods.
#[test]
fn residuals_ignore_a_shift_in_time() {
    let (reference, e0, spot) = corner_run(0);
    let (_, e1, _) = corner_run(37);
    let r0 = residuals(&reference, &spot, &e0, &tips_of(&e0.actual));
    let r1 = residuals(&reference, &spot, &e1, &tips_of(&e1.actual));
    let worst = r0
        .iter()
        .zip(&r1)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst <= 1e-12, "largest change {worst}");
}
