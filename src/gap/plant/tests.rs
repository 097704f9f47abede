//! Unit tests of `crate::gap::plant`.

use super::*;
use crate::motion::simulate_axis;

fn command() -> Vec<f64> {
    (0..3000)
        .map(|i| 150.0 + 20.0 * (2.0 * std::f64::consts::PI * 0.8 * i as f64 * 0.001).sin())
        .collect()
}

#[test]
fn friction_plant_with_zero_friction_equals_simulate_axis_below_0_1_um() {
    let cmd = command();
    for servo in [
        ServoAxis::first_order(30.0, 0.5),
        ServoAxis {
            kv: 40.0,
            kff: 0.7,
            kp_v: Some(500.0),
            ti_v: Some(0.01),
            tc: Some(0.0008),
        },
        ServoAxis {
            kv: 40.0,
            kff: 0.0,
            kp_v: Some(500.0),
            ti_v: None,
            tc: None,
        },
    ] {
        let p = AxisPlant::new("X", &servo, 0.001).unwrap();
        let reference = simulate_axis(&servo, &cmd, 0.001).unwrap();
        let worst = p
            .with_friction(0.0, &cmd)
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-7, "{servo:?}: {worst:e} mm");
        // and friction, when present, changes the answer by micrometres near reversals
        let with = p.with_friction(if p.has_velocity_loop() { 300.0 } else { 0.5 }, &cmd);
        let diff = with
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            diff > 1e-3 && diff < 0.1,
            "{servo:?}: friction effect {diff}"
        );
    }
}

#[test]
fn play_operator_lags_by_half_the_gap_and_steps_at_reversals() {
    let motor: Vec<f64> = (0..200)
        .map(|i| {
            if i < 100 {
                i as f64 * 0.01
            } else {
                (200 - i) as f64 * 0.01
            }
        })
        .collect();
    let table = play(&motor, 0.02, 0.0);
    assert!((motor[50] - table[50] - 0.01).abs() < 1e-12);
    assert!((table[150] - motor[150] - 0.01).abs() < 1e-12);
    assert_eq!(play(&motor, 0.0, 0.0), motor);
}
