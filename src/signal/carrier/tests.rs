//! Unit tests of `crate::signal::carrier`.

use super::*;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// RMS of `est − truth` (mm).
fn rms_error(est: &[f64], truth: &[f64]) -> f64 {
    let ss: f64 = est.iter().zip(truth).map(|(a, b)| (a - b).powi(2)).sum();
    (ss / truth.len() as f64).sqrt()
}

fn noisy_sine(n: usize, f: f64, amp: f64, sigma: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let nd = Normal::new(0.0, sigma).unwrap();
    let truth: Vec<f64> = (0..n)
        .map(|t| amp * (2.0 * std::f64::consts::PI * f * t as f64 + 0.3).sin())
        .collect();
    let x = truth.iter().map(|v| v + nd.sample(&mut rng)).collect();
    (truth, x)
}

#[test]
fn steady_carrier_costs_few_degrees_of_freedom() {
    // A steady sinusoid in white noise: GCV goes to the penalty's null space (a linear
    // envelope: 4 degrees of freedom), so the error is ~σ·√(4/n), far below a
    // broadband smoother's.
    let (n, sigma) = (2025, 0.005);
    let (truth, x) = noisy_sine(n, 0.008, 0.04, sigma, 1);
    let (f, power) = strongest_line(&x).unwrap();
    assert!((f - 0.008).abs() < 0.2 / n as f64, "f = {f}");
    assert!(power > 0.04 * 0.04 * n as f64 / 6.0 * 0.9, "power {power}");
    let fit = Carrier::new(n, f).unwrap().fit(&x).unwrap();
    assert!(fit.edf < 6.0, "edf {}", fit.edf);
    let rms = rms_error(&fit.signal, &truth);
    assert!(rms < 3.0 * sigma * (6.0 / n as f64).sqrt(), "rms {rms}");
    let smooth = super::super::whittaker::whittaker(&x, 4, None).unwrap();
    assert!(
        smooth.edf > 20.0 * fit.edf / 6.0,
        "whittaker edf {}",
        smooth.edf
    );
}

/// Not tuned to the paper's one signal: steady lines at other frequencies, amplitudes,
/// noise levels and record lengths are found and fitted with a handful of degrees of
/// freedom, to within a few σ·√(edf/n) of the truth.
#[test]
fn steady_carriers_of_other_signals() {
    for (i, &(n, f, amp, sigma)) in [
        (1000, 0.012, 0.02, 0.004),
        (3000, 0.03, 0.005, 0.002),
        (5000, 0.0041, 0.1, 0.01),
        (8192, 0.11, 0.008, 0.003),
        (20000, 0.0007, 0.03, 0.005),
    ]
    .iter()
    .enumerate()
    {
        let (truth, x) = noisy_sine(n, f, amp, sigma, 10 + i as u64);
        let (fh, _) = strongest_line(&x).unwrap();
        assert!((fh - f).abs() < 0.5 / n as f64, "case {i}: f {fh} vs {f}");
        let fit = Carrier::new(n, fh).unwrap().fit(&x).unwrap();
        assert!(fit.edf < 8.0, "case {i}: edf {}", fit.edf);
        let rms = rms_error(&fit.signal, &truth);
        assert!(
            rms < 3.0 * sigma * (8.0 / n as f64).sqrt(),
            "case {i}: rms {rms}"
        );
    }
}

#[test]
fn changing_envelope_is_followed() {
    // Amplitude rising linearly then falling: the envelope basis follows it.
    let n = 4000;
    let f = 0.05;
    let truth: Vec<f64> = (0..n)
        .map(|t| {
            let u = t as f64 / n as f64;
            let env = 0.01 * (1.0 + 2.0 * (std::f64::consts::PI * u).sin());
            env * (2.0 * std::f64::consts::PI * f * t as f64).cos()
        })
        .collect();
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let nd = Normal::new(0.0, 0.002).unwrap();
    let x: Vec<f64> = truth.iter().map(|v| v + nd.sample(&mut rng)).collect();
    let fit = Carrier::new(n, f).unwrap().fit(&x).unwrap();
    let max_err = fit
        .signal
        .iter()
        .zip(&truth)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(max_err < 0.0015, "max error {max_err}");
}

#[test]
fn no_line_in_short_or_bad_input() {
    assert!(strongest_line(&[0.0; 20]).is_none());
    assert!(Carrier::new(100, 0.0).is_err());
    assert!(Carrier::new(100, 0.6).is_err());
    let c = Carrier::new(100, 0.1).unwrap();
    assert!(c.fit(&[0.0; 50]).is_err());
}
