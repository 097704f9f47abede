//! Unit tests of `crate::gap::unexplained`.

use super::*;

fn names() -> Vec<String> {
    vec!["X".into(), "Y".into()]
}

/// A 2 s ripple of 18 µm on Y comes back in time, on Y, with its amplitude; a 5 mm
/// position-periodic error on X (X moving at varying speed) comes back in position.
#[test]
fn ripple_in_time_and_error_in_position_are_found_on_their_axes() {
    let n = 12_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.001).collect();
    // X sweeps 100..160 mm with a speed that varies (not a constant-velocity map t -> x)
    let x: Vec<f64> = t
        .iter()
        .map(|t| 130.0 + 30.0 * (0.5 * t + 0.3 * (1.3 * t).sin()).sin())
        .collect();
    let y: Vec<f64> = t.iter().map(|t| 80.0 + 20.0 * (0.7 * t).cos()).collect();
    let rx: Vec<f64> = x
        .iter()
        .map(|x| 0.003 * (std::f64::consts::TAU * x / 5.0 + 0.4).sin())
        .collect();
    let ry: Vec<f64> = t
        .iter()
        .map(|t| 0.018 * (std::f64::consts::TAU * t / 2.0).sin())
        .collect();
    let found = periodic_components(&[rx, ry], &[x, y], &names(), 0.001);
    eprintln!("{found:?}");
    let y_comp = found.iter().find(|c| c.axis == "Y").expect("Y ripple");
    let ps = y_comp.period_s.expect("in time");
    assert!((ps - 2.0).abs() < 0.2, "{ps}");
    assert!((y_comp.amplitude - 0.018).abs() < 0.002);
    let x_comp = found.iter().find(|c| c.axis == "X").expect("X cyclic");
    let pm = x_comp.period_mm.expect("in position");
    assert!((pm - 5.0).abs() < 0.25, "{pm}");
    assert!((x_comp.amplitude - 0.003).abs() < 0.0005);
}

/// White noise alone yields nothing strong.
#[test]
fn noise_alone_gives_no_component() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let n = 5000;
    let r: Vec<f64> = (0..n).map(|_| rng.random_range(-0.001..0.001)).collect();
    let x: Vec<f64> = (0..n).map(|i| 100.0 + 0.01 * i as f64).collect();
    let found = periodic_components(&[r], &[x], &names()[..1], 0.001);
    assert!(found.is_empty(), "{found:?}");
}
