//! ISO 230-4 cases known in closed form, and the orthogonal fit against the algebraic one
//! and a slow reference.

use super::*;
use crate::metrology::circle::fit_circle_kasa;
use crate::numeric::brent;

/// `n` points at angles `theta0 + k·span/n` with radius `r(θ)` about `c`.
fn ring(c: [f64; 2], n: usize, theta0: f64, span: f64, r: impl Fn(f64) -> f64) -> Vec<[f64; 2]> {
    (0..n)
        .map(|k| {
            let t = theta0 + span * k as f64 / n as f64;
            [c[0] + r(t) * t.cos(), c[1] + r(t) * t.sin()]
        })
        .collect()
}

#[test]
fn three_lobes_about_an_offset_centre() {
    // r(θ) = 50.003 + 0.004 cos 3θ about (12.5, −7.25), 360 points, nominal 50 mm.
    // The lobes are orthogonal to cos θ, sin θ and 1 over a full uniform turn, so the
    // least-squares circle is the true centre and radius 50.003; G = 2·0.004 = 0.008,
    // F_max = 50.007 − 50 = 0.007, F_min = 49.999 − 50 = −0.001.
    let c = [12.5, -7.25];
    let pts = ring(c, 360, 0.1, TAU, |t| 50.003 + 0.004 * (3.0 * t).cos());
    let e = evaluate_circle(&pts, 50.0, None).unwrap();
    assert!(
        (e.centre[0] - c[0]).abs() < 1e-9 && (e.centre[1] - c[1]).abs() < 1e-9,
        "{:?}",
        e.centre
    );
    assert!((e.radius_fit - 50.003).abs() < 1e-9);
    // 360 samples of cos 3θ from 0.1 rad reach ±1 within 1 − cos(1.5°·3/2) ≈ 3e-4.
    assert!((e.g - 0.008).abs() < 3e-6, "G = {}", e.g);
    assert!((e.f_max - 0.007).abs() < 2e-6, "F_max = {}", e.f_max);
    assert!((e.f_min + 0.001).abs() < 2e-6, "F_min = {}", e.f_min);
    assert!(e.centre_fitted);
}

#[test]
fn a_given_centre_is_used_as_is() {
    // A perfect circle of radius 20 about the origin read about (0.01, 0): the radii run
    // from 19.99 to 20.01, so G = 0.02 and F = ±0.01 (to first order in 0.01/20).
    let pts = ring([0.0, 0.0], 720, 0.0, TAU, |_| 20.0);
    let e = evaluate_circle(&pts, 20.0, Some([0.01, 0.0])).unwrap();
    assert!(!e.centre_fitted && e.centre == [0.01, 0.0]);
    assert!(
        (e.g - 0.02).abs() < 1e-6 && (e.f_max - 0.01).abs() < 1e-5 && (e.f_min + 0.01).abs() < 1e-5
    );
    let fitted = evaluate_circle(&pts, 20.0, None).unwrap();
    assert!(
        fitted.g < 1e-9,
        "about the fitted centre a perfect circle has G = 0"
    );
}

/// Slow oracle: the orthogonal cost minimised over the centre by Brent along x and y in
/// turn (radius = mean distance), from the algebraic centre.
fn reference_orthogonal_centre(pts: &[[f64; 2]], start: [f64; 2]) -> [f64; 2] {
    let cost = |c: [f64; 2]| {
        let r: Vec<f64> = pts
            .iter()
            .map(|p| (p[0] - c[0]).hypot(p[1] - c[1]))
            .collect();
        let mean = r.iter().sum::<f64>() / r.len() as f64;
        r.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>()
    };
    let mut c = start;
    for _ in 0..400 {
        let (x, _) = brent::minimize(|x| cost([x, c[1]]), c[0] - 1.0, c[0] + 1.0, 1e-13, 200);
        c[0] = x;
        let (y, _) = brent::minimize(|y| cost([c[0], y]), c[1] - 1.0, c[1] + 1.0, 1e-13, 200);
        c[1] = y;
    }
    c
}

#[test]
fn noisy_partial_arc_uses_the_orthogonal_fit_not_the_algebraic_one() {
    // 150 points on 120° of a R 25 mm circle about (3, −2), radial noise ±0.05 mm.
    let mut seed = 7_u64;
    let mut noise = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.1
    };
    let c = [3.0, -2.0];
    let pts: Vec<[f64; 2]> = ring(c, 150, 0.3, TAU / 3.0, |_| 25.0)
        .into_iter()
        .map(|p| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            let k = 1.0 + noise() / 25.0;
            [c[0] + dx * k, c[1] + dy * k]
        })
        .collect();
    let kasa = fit_circle_kasa("points", &pts).unwrap();
    let ortho = fit_circle("points", &pts).unwrap();
    let oracle = reference_orthogonal_centre(&pts, kasa.centre);
    let gap = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    assert!(
        gap(ortho.centre, oracle) < 1e-6,
        "fit {:?} oracle {oracle:?}",
        ortho.centre
    );
    assert!(
        gap(ortho.centre, kasa.centre) > 1e-3,
        "the two fits differ here: algebraic {:?}, orthogonal {:?}",
        kasa.centre,
        ortho.centre
    );
    assert!(ortho.orthogonal_cost(&pts) < kasa.orthogonal_cost(&pts));
    let e = evaluate_circle(&pts, 25.0, None).unwrap();
    assert_eq!(e.centre, ortho.centre);
    assert!((e.radius_fit - ortho.radius).abs() < 1e-9);
}

#[test]
fn hysteresis_of_opposite_lobes_and_of_a_size_step() {
    // CW r = 40 + 0.003 sin 2θ, CCW r = 40 − 0.003 sin 2θ: H = 0.006 at 45° (interpolation
    // between CW points 0.5° apart loses 0.003·(1 − cos 1°) ≈ 5e-7).
    let c = [1.0, 2.0];
    let cw = ring(c, 360, TAU / 720.0, TAU, |t| 40.0 + 0.003 * (2.0 * t).sin());
    let ccw = ring(c, 360, 0.0, TAU, |t| 40.0 - 0.003 * (2.0 * t).sin());
    let h = circular_hysteresis(&cw, &ccw, None).unwrap();
    assert!((h.h - 0.006).abs() < 1e-6, "H = {}", h.h);
    assert!((h.centre[0] - 1.0).abs() < 1e-9 && (h.centre[1] - 2.0).abs() < 1e-9);
    let at = h.at_angle_deg.rem_euclid(90.0);
    assert!((at - 45.0).abs() < 1.0, "{}", h.at_angle_deg);
    // Two round paths 0.004 mm apart in size: H = 0.004 everywhere.
    let big = ring(c, 200, 0.0, TAU, |_| 40.002);
    let small = ring(c, 300, 0.01, TAU, |_| 39.998);
    let h = circular_hysteresis(&big, &small, Some(c)).unwrap();
    assert!((h.h - 0.004).abs() < 1e-9, "H = {}", h.h);
}

#[test]
fn bad_input_is_refused() {
    let pts = ring([0.0, 0.0], 10, 0.0, TAU, |_| 5.0);
    assert!(matches!(
        evaluate_circle(&pts, 0.0, None),
        Err(Error::Invalid {
            field: "radius",
            ..
        })
    ));
    assert!(matches!(
        evaluate_circle(&pts[..2], 5.0, None),
        Err(Error::Degenerate { .. })
    ));
    let line: Vec<[f64; 2]> = (0..10).map(|k| [k as f64, 2.0 * k as f64]).collect();
    assert!(matches!(
        evaluate_circle(&line, 5.0, None),
        Err(Error::Degenerate { .. })
    ));
    let mut bad = pts.clone();
    bad[3][1] = f64::NAN;
    assert!(matches!(
        evaluate_circle(&bad, 5.0, None),
        Err(Error::NonFinite { index: 3, .. })
    ));
}
