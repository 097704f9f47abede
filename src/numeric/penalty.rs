//! Difference penalties `‖D_d c‖²` of P-splines and Whittaker smoothers: the stencil, the dense
//! matrix `D_dᵀ D_d`, and its eigenvalues under reflective ends.
//!
//! Written here: three lines each, built once for every core (the decomposition's Whittaker
//! smoothers and carriers, the volumetric P-spline) instead of once per core.

use nalgebra::DMatrix;

/// The d-th forward-difference stencil `c_j = (−1)^(d−j) C(d, j)`, j = 0..=d
/// (`[1]`, `[−1, 1]`, `[1, −2, 1]`, ...): row r of `D_d` has `c_j` at column `r + j`.
///
/// Reference: Eilers & Marx 1996, Statist. Sci. 11, §2 (difference penalties).
pub fn difference_stencil(d: usize) -> Vec<f64> {
    let mut c = vec![1.0f64];
    for _ in 0..d {
        let mut next = vec![0.0; c.len() + 1];
        for (j, &v) in c.iter().enumerate() {
            next[j] -= v;
            next[j + 1] += v;
        }
        c = next;
    }
    c
}

/// The dense `n × n` penalty `D_dᵀ D_d` of the d-th differences of `n` coefficients
/// (`D_d` is `(n − d) × n`; all zeros when `n ≤ d`). Entries are small integers, exact.
///
/// Formula: `P[r+a][r+b] += c_a c_b` over rows r = 0..n−d, with `c` = [`difference_stencil`].
/// Reference: Eilers & Marx 1996, Statist. Sci. 11, §2.
pub fn difference_penalty(n: usize, d: usize) -> DMatrix<f64> {
    let c = difference_stencil(d);
    let mut p = DMatrix::<f64>::zeros(n, n);
    for r in 0..n.saturating_sub(d) {
        for a in 0..=d {
            for b in 0..=d {
                p[(r + a, r + b)] += c[a] * c[b];
            }
        }
    }
    p
}

/// Eigenvalues `(2 − 2cos(πk/n))^d`, k = 0..n, of the d-th difference penalty with reflective
/// ends, which the DCT-II diagonalises (dimensionless).
///
/// Reference: Garcia 2010, Comput. Stat. Data Anal. 54, eq. 9.
/// Known bad cases: the natural-ends penalty of [`difference_penalty`] has slightly different
/// eigenvalues; the smoothers use these only for GCV and the degrees of freedom.
pub fn reflective_eigenvalues(n: usize, d: usize) -> Vec<f64> {
    (0..n)
        .map(|k| (2.0 - 2.0 * (std::f64::consts::PI * k as f64 / n as f64).cos()).powi(d as i32))
        .collect()
}

#[cfg(test)]
mod tests;
