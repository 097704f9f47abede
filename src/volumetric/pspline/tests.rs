//! Unit tests of `crate::volumetric::pspline`.

use super::*;

fn grid(n: [usize; 3], f: impl Fn([f64; 3]) -> [f64; 3]) -> VolumetricData {
    let mut nodes = vec![];
    for i in 0..n[0] {
        for j in 0..n[1] {
            for k in 0..n[2] {
                nodes.push([
                    800.0 * i as f64 / (n[0] - 1) as f64,
                    500.0 * j as f64 / (n[1] - 1) as f64,
                    400.0 * k as f64 / (n[2] - 1) as f64,
                ]);
            }
        }
    }
    let errors = nodes.iter().map(|&p| f(p)).collect();
    VolumetricData { nodes, errors }
}

#[test]
fn basis_is_a_partition_of_unity() {
    for q in [0.0, 13.7, 250.0, 399.9, 400.0, -5.0, 500.0] {
        let (_, b) = uniform_cubic(q, [0.0, 400.0], 3);
        assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-14, "{q}");
    }
}

#[test]
fn reproduces_a_trilinear_field_exactly() {
    // the penalty's null space: any λ leaves it untouched
    let f = |p: [f64; 3]| {
        let v = 1e-3 * (1.0 + p[0] / 800.0 - 2.0 * p[1] / 500.0 + p[0] * p[2] / 3.2e5);
        [v, -v, 0.5 * v]
    };
    let d = grid([7, 6, 5], f);
    let s = SmoothingSpline3::fit(&d, [3, 2, 2]).unwrap();
    for p in [
        [10.0, 20.0, 30.0],
        [777.0, 123.0, 399.0],
        [400.0, 250.0, 200.0],
    ] {
        let (a, b) = (s.eval(p), f(p));
        for j in 0..3 {
            assert!((a[j] - b[j]).abs() < 1e-9, "{p:?} {a:?} {b:?}");
        }
    }
    assert!(s.coef.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn smooths_a_sag_and_rejects_noise() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let sag = |p: [f64; 3]| {
        let v = -8e-3
            * (std::f64::consts::PI * p[0] / 800.0).sin()
            * (std::f64::consts::PI * p[1] / 500.0).sin();
        [0.0, 0.0, v]
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let noise = Normal::new(0.0, 1e-3).unwrap();
    let mut d = grid([7, 6, 5], sag);
    for e in &mut d.errors {
        for v in e.iter_mut() {
            *v += noise.sample(&mut rng);
        }
    }
    let s = SmoothingSpline3::fit(&d, [3, 2, 2]).unwrap();
    let mut se = 0.0;
    let mut n = 0.0;
    for i in 0..20 {
        for j in 0..20 {
            let p = [
                800.0 * (i as f64 + 0.5) / 20.0,
                500.0 * (j as f64 + 0.5) / 20.0,
                137.0,
            ];
            let (a, b) = (s.eval(p), sag(p));
            se += (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
            n += 1.0;
        }
    }
    let rms = (se / n).sqrt();
    // noise alone is 1.73 µm per vector; the smoothed field must be well below it
    assert!(rms < 0.8e-3, "rms {rms}");
    assert!(s.effective_parameters < s.coef.len() as f64);
}

#[test]
fn rejects_bad_pieces() {
    let d = grid([3, 3, 3], |_| [0.0; 3]);
    assert!(SmoothingSpline3::fit(&d, [0, 1, 1]).is_err());
    assert!(SmoothingSpline3::fit(&d, [1, 9, 1]).is_err());
}
