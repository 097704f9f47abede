//! Unit tests of `crate::signal::whittaker`.

use super::*;

#[test]
fn polynomials_below_the_order_pass_unchanged() {
    let x: Vec<f64> = (0..200)
        .map(|k| {
            let t = k as f64 / 10.0;
            1.0 - 0.5 * t + 0.02 * t * t * t
        })
        .collect();
    let s = whittaker(&x, 4, Some(1e6)).unwrap();
    let err = x
        .iter()
        .zip(&s.signal)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-7, "{err}");
}

#[test]
fn banded_solve_matches_dense() {
    let x: Vec<f64> = (0..30).map(|k| ((k * k) as f64 * 0.37).sin()).collect();
    let lam = 3.5;
    let z = solve_banded(&x, 2, lam);
    // Residual of (I + λDᵀD) z = x computed densely.
    let n = x.len();
    let mut dz = vec![0.0; n - 2];
    for (r, v) in dz.iter_mut().enumerate() {
        *v = z[r] - 2.0 * z[r + 1] + z[r + 2];
    }
    for i in 0..n {
        let mut dtdz = 0.0;
        for (r, v) in dz.iter().enumerate() {
            let coef = match i as isize - r as isize {
                0 => 1.0,
                1 => -2.0,
                2 => 1.0,
                _ => 0.0,
            };
            dtdz += coef * v;
        }
        assert!((z[i] + lam * dtdz - x[i]).abs() < 1e-12);
    }
}

#[test]
fn dct_power_is_parseval() {
    let x: Vec<f64> = (0..97)
        .map(|k| (k as f64 * 0.3).cos() + 0.1 * k as f64)
        .collect();
    let p: f64 = dct_power(&x).iter().sum();
    let e: f64 = x.iter().map(|v| v * v).sum();
    assert!((p - e).abs() < 1e-9 * e);
}

#[test]
fn gcv_removes_white_noise_from_a_smooth_curve() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let truth: Vec<f64> = (0..1000).map(|k| (k as f64 / 80.0).sin()).collect();
    let x: Vec<f64> = truth.iter().map(|t| t + noise.sample(&mut rng)).collect();
    let s = whittaker(&x, 3, None).unwrap();
    let rms = |a: &[f64]| {
        (a.iter()
            .zip(&truth)
            .map(|(u, v)| (u - v).powi(2))
            .sum::<f64>()
            / 1000.0)
            .sqrt()
    };
    assert!(
        rms(&s.signal) < 0.3 * rms(&x),
        "{} vs {}",
        rms(&s.signal),
        rms(&x)
    );
}

#[test]
fn gcv_sums_avx2_matches_portable() {
    // Bit for bit: the AVX2 build of the loop performs the same operations in the same lane
    // order. Lengths with and without a tail past the last group of four.
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        for n in [5usize, 64, 2025, 2027] {
            let c2: Vec<f64> = (0..n).map(|k| ((k * 7919) % 997) as f64 * 1e-6).collect();
            let e = crate::numeric::penalty::reflective_eigenvalues(n, 4);
            for lam in [1e-4, 3.7, 1e6, 1e11] {
                // SAFETY: AVX2 checked above.
                let fast = unsafe { gcv_sums_avx2(&c2, &e, lam) };
                let slow = gcv_sums_portable(&c2, &e, lam);
                assert_eq!(fast.0.to_bits(), slow.0.to_bits(), "rss n {n} λ {lam}");
                assert_eq!(fast.1.to_bits(), slow.1.to_bits(), "tr n {n} λ {lam}");
            }
        }
    } else {
        eprintln!(
            "gcv_sums_avx2_matches_portable: no AVX2 on this CPU, only the portable loop runs"
        );
    }
}
