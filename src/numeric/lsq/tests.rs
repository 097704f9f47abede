//! Tests of both rank policies against nalgebra's SVD.

use super::*;

#[test]
fn recovers_coefficients_and_drops_duplicate_column() {
    // y = 2 + 3 t ; column 2 duplicates column 1 (times 5) and must be dropped
    let mut ls = LeastSquares::new(3);
    for i in 0..20 {
        let t = i as f64 * 0.1;
        ls.add(&[(0, 1.0), (1, t), (2, 5.0 * t)], 2.0 + 3.0 * t);
    }
    let s = ls.solve().unwrap();
    assert_eq!(s.kept, vec![true, true, false]);
    assert!((s.coef[0] - 2.0).abs() < 1e-10 && (s.coef[1] - 3.0).abs() < 1e-10 && s.coef[2] == 0.0);
    assert!(ls.rss(&s.coef) < 1e-18);
    // only the constant allowed: mean of y, RSS = Σ (y - ȳ)²
    let m = ls.solve_masked(&[true, false, false]).unwrap();
    assert!((m.coef[0] - 2.0 - 3.0 * 0.95).abs() < 1e-10);
    let want: f64 = (0..20)
        .map(|i| (3.0 * (i as f64 * 0.1 - 0.95)).powi(2))
        .sum();
    assert!((ls.rss(&m.coef) - want).abs() < 1e-9);
}

#[test]
fn matches_nalgebra_svd_on_a_random_full_rank_problem() {
    let (m, n) = (40, 5);
    let mut a = nalgebra::DMatrix::<f64>::zeros(m, n);
    let mut y = nalgebra::DVector::<f64>::zeros(m);
    let mut ls = LeastSquares::new(n);
    let mut s = 12345u64;
    let mut rnd = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for i in 0..m {
        let row: Vec<(usize, f64)> = (0..n).map(|j| (j, rnd())).collect();
        for &(j, v) in &row {
            a[(i, j)] = v;
        }
        y[i] = rnd();
        ls.add(&row, y[i]);
    }
    let want = a.svd(true, true).solve(&y, 1e-12).unwrap();
    let got = ls.solve().unwrap();
    for j in 0..n {
        assert!((got.coef[j] - want[j]).abs() < 1e-9, "{j}");
    }
}

#[test]
fn truncated_svd_zeroes_dead_columns_and_skips_unweighted_rows() {
    // y = 1 + 2 t on the weighted rows; column 2 is zero on them (dead), row 5 is held out.
    let rows: Vec<Vec<f64>> = (0..6)
        .map(|i| {
            let t = i as f64;
            vec![1.0, t, if i == 5 { 1.0 } else { 0.0 }]
        })
        .collect();
    let y: Vec<f64> = (0..6).map(|i| 1.0 + 2.0 * i as f64).collect();
    let w = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0];
    let c = truncated_svd(&rows, &y, &w);
    assert!(
        (c[0] - 1.0).abs() < 1e-10 && (c[1] - 2.0).abs() < 1e-10,
        "{c:?}"
    );
    assert_eq!(c[2], 0.0);
    assert_eq!(truncated_svd(&rows, &y, &[0.0; 6]), vec![0.0; 3]);
}
