//! Tests of the difference penalties.

use super::*;

#[test]
fn stencils_are_binomial_differences() {
    assert_eq!(difference_stencil(0), vec![1.0]);
    assert_eq!(difference_stencil(1), vec![-1.0, 1.0]);
    assert_eq!(difference_stencil(2), vec![1.0, -2.0, 1.0]);
    assert_eq!(difference_stencil(3), vec![-1.0, 3.0, -3.0, 1.0]);
}

/// The slow oracle: `DᵀD` from the explicit difference matrix.
fn reference_dense(n: usize, d: usize) -> DMatrix<f64> {
    let c = difference_stencil(d);
    let mut dm = DMatrix::zeros(n.saturating_sub(d), n);
    for r in 0..n.saturating_sub(d) {
        for (j, &v) in c.iter().enumerate() {
            dm[(r, r + j)] = v;
        }
    }
    dm.transpose() * dm
}

#[test]
fn penalty_matches_reference_dense_and_kills_polynomials() {
    for (n, d) in [(1, 2), (2, 2), (3, 2), (6, 2), (9, 3), (12, 4)] {
        let p = difference_penalty(n, d);
        assert_eq!(p, reference_dense(n, d), "n {n} d {d}");
        // Polynomials of degree < d are in the null space.
        if n > d {
            let v = nalgebra::DVector::from_fn(n, |i, _| (i as f64).powi(d as i32 - 1));
            assert!((&p * v).amax() < 1e-9);
        }
    }
}

#[test]
fn reflective_eigenvalues_start_at_zero_and_stay_below_4_to_the_d() {
    let e = reflective_eigenvalues(50, 2);
    assert_eq!(e[0], 0.0);
    assert!(e.iter().all(|&v| (0.0..16.0).contains(&v)));
}
