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

/// [`solve_banded`] as written before it was compiled per order (every band loop of length
/// d at run time): the oracle of the per-order versions, which must give the same bits.
fn reference_solve_banded(x: &[f64], d: usize, lam: f64) -> Vec<f64> {
    let n = x.len();
    let c = difference_stencil(d);
    let w = d + 1;
    let mut a = vec![0.0; n * w];
    for r in 0..n - d {
        for p in 0..=d {
            for q in 0..=p {
                a[(r + p) * w + (p - q)] += lam * c[p] * c[q];
            }
        }
    }
    for i in 0..n {
        a[i * w] += 1.0;
    }
    let mut inv = vec![0.0; n];
    let mut t = [0.0; 7];
    for i in 0..n {
        let j0 = i.saturating_sub(d);
        let row = i * w;
        let mut dv = a[row];
        for j in j0..i {
            let jrow = j * w;
            let mut v = a[row + (i - j)];
            for k in j0.max(j.saturating_sub(d))..j {
                v -= t[k - j0] * a[jrow + (j - k)];
            }
            let l = v * inv[j];
            a[row + (i - j)] = l;
            t[j - j0] = l * a[jrow];
            dv -= l * t[j - j0];
        }
        a[row] = dv;
        inv[i] = 1.0 / dv;
    }
    let substitute = |z: &mut [f64]| {
        for i in 1..n {
            let row = &a[i * w..i * w + w];
            let mut v = z[i];
            for s in (1..=d.min(i)).rev() {
                v -= row[s] * z[i - s];
            }
            z[i] = v;
        }
        for (zi, di) in z.iter_mut().zip(&inv) {
            *zi *= di;
        }
        for i in (0..n - 1).rev() {
            let mut v = z[i];
            for s in (1..=d.min(n - 1 - i)).rev() {
                v -= a[(i + s) * w + s] * z[i + s];
            }
            z[i] = v;
        }
    };
    let mut z = x.to_vec();
    substitute(&mut z);
    let lc: Vec<f64> = c.iter().map(|cj| lam * cj).collect();
    let mut resid = vec![0.0; n];
    for _ in 0..2 {
        for ((r, xi), zi) in resid.iter_mut().zip(x).zip(&z) {
            *r = xi - zi;
        }
        for r in 0..n - d {
            let v: f64 = c.iter().zip(&z[r..=r + d]).map(|(cj, zj)| cj * zj).sum();
            for (res, lcj) in resid[r..=r + d].iter_mut().zip(&lc) {
                *res -= lcj * v;
            }
        }
        substitute(&mut resid);
        for (zi, di) in z.iter_mut().zip(&resid) {
            *zi += di;
        }
    }
    z
}

#[test]
fn banded_solve_per_order_matches_reference_bit_for_bit() {
    for d in 1..=6 {
        for n in [d + 2, d + 5, 2 * d + 1, 64, 2025] {
            let x: Vec<f64> = (0..n)
                .map(|k| ((k * 7919) % 1000) as f64 * 1e-3 - 0.5 + (k as f64 * 0.01).sin())
                .collect();
            for lam in [0.3, 1e3, 1e9] {
                let fast = solve_banded(&x, d, lam);
                let slow = reference_solve_banded(&x, d, lam);
                assert!(
                    fast.iter()
                        .zip(&slow)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "d = {d}, n = {n}, lambda = {lam}"
                );
            }
        }
    }
}
