//! Tests of the tridiagonal solve against a dense LU solve.

use super::*;

/// The slow oracle: the same system solved densely by nalgebra's LU.
fn reference_dense(lower: &[f64], diag: &[f64], upper: &[f64], rhs: &[f64]) -> Vec<f64> {
    let n = diag.len();
    let a = nalgebra::DMatrix::from_fn(n, n, |i, j| {
        if i == j {
            diag[i]
        } else if j + 1 == i {
            lower[i]
        } else if i + 1 == j {
            upper[i]
        } else {
            0.0
        }
    });
    let b = nalgebra::DVector::from_column_slice(rhs);
    a.lu()
        .solve(&b)
        .expect("nonsingular")
        .iter()
        .copied()
        .collect()
}

#[test]
fn reference_dense_agrees_on_diagonally_dominant_systems() {
    let mut s = 7u64;
    let mut rnd = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for n in [1, 2, 3, 7, 40] {
        let lower: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let upper: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let diag: Vec<f64> = (0..n).map(|_| 2.0 + rnd()).collect();
        let rhs: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let want = reference_dense(&lower, &diag, &upper, &rhs);
        let mut got = rhs.clone();
        solve(&lower, &diag, &upper, &mut got);
        let mut got3: Vec<[f64; 3]> = rhs.iter().map(|&r| [r, 2.0 * r, -r]).collect();
        solve(&lower, &diag, &upper, &mut got3);
        for i in 0..n {
            assert!((got[i] - want[i]).abs() < 1e-12, "n {n} row {i}");
            assert_eq!(got3[i][0], got[i]);
            assert!((got3[i][1] - 2.0 * want[i]).abs() < 1e-12);
            assert!((got3[i][2] + want[i]).abs() < 1e-12);
        }
    }
}

#[test]
fn factors_are_reused_after_clear() {
    let mut t = Tridiagonal::new();
    t.push_row(0.0, 4.0, 1.0);
    t.push_row(1.0, 4.0, 0.0);
    let mut x = [5.0, 5.0];
    t.solve_in_place(&mut x);
    assert!((x[0] - 1.0).abs() < 1e-15 && (x[1] - 1.0).abs() < 1e-15);
    t.clear();
    assert!(t.is_empty());
    t.push_row(0.0, 2.0, 0.0);
    let mut y = [3.0];
    t.solve_in_place(&mut y);
    assert_eq!(y, [1.5]);
}
