//! Linear least squares that drop columns the data cannot identify, under two named rank
//! policies:
//!
//! - **ordered** ([`LeastSquares::solve`]): columns are taken in the caller's order and a column
//!   that is (numerically) a combination of earlier kept columns is dropped, coefficient 0.
//!   For models whose columns have a meaning and a priority (the ISO 230-1 error motions).
//! - **truncated** ([`truncated_svd`]): columns the data do not excite are zeroed, then the
//!   minimum-norm solution over singular values above 1e-9 of the largest. For models whose
//!   columns are symmetric alternatives, none preferred (the part effects of the gap core).
//!
//! Written here: nalgebra has no rank-revealing solver that respects a given column order,
//! and its SVD solve keeps huge coefficients on columns that are numerically zero.

use nalgebra::{DMatrix, DVector};

/// Why a least-squares solve failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A coefficient came out infinite or NaN (non-finite data).
    #[error("least-squares solution is not finite")]
    NotFinite,
    /// No penalty weight left the penalised normal equations positive definite.
    #[error("penalised normal equations are singular")]
    Singular,
}

/// Least-squares solution of `A c ≈ y` accumulated row by row (the **ordered** rank policy).
///
/// Columns are taken in the caller's order; a column that is (numerically) a linear
/// combination of earlier kept columns is dropped and its coefficient fixed to 0. This
/// is what makes the ISO 230-1 fit well defined: with one tool offset the Z-axis
/// angular errors only act through that offset and are indistinguishable from Z
/// straightness, so they come after the translational columns and are dropped.
/// Hand-written (normal equations + ordered Cholesky with skipped pivots, ~60 lines)
/// because nalgebra has no rank-revealing solver that respects a given column order.
pub struct LeastSquares {
    n: usize,
    gram: Vec<f64>,
    rhs: Vec<f64>,
    yy: f64,
    rows: usize,
}

/// A solved system: coefficients (0 for dropped columns) and which columns were kept.
pub struct Solution {
    /// Coefficient per column (0 for a dropped column).
    pub coef: Vec<f64>,
    /// Whether each column was kept.
    pub kept: Vec<bool>,
}

/// A column whose part not explained by earlier columns has less than this share of
/// its squared norm is treated as dependent.
const DEPENDENT: f64 = 1e-9;

impl LeastSquares {
    /// An empty system of `n` columns.
    pub fn new(n: usize) -> Self {
        LeastSquares {
            n,
            gram: vec![0.0; n * n],
            rhs: vec![0.0; n],
            yy: 0.0,
            rows: 0,
        }
    }

    /// Adds one equation `row · c ≈ y` (row given sparsely as (column, value) pairs).
    pub fn add(&mut self, row: &[(usize, f64)], y: f64) {
        self.yy += y * y;
        self.rows += 1;
        for &(i, a) in row {
            self.rhs[i] += a * y;
            for &(j, b) in row {
                if j >= i {
                    self.gram[i * self.n + j] += a * b;
                }
            }
        }
    }

    /// Solves the normal equations with an ordered Cholesky factorisation that skips
    /// dependent pivots (columns scaled to unit norm first).
    pub fn solve(&self) -> Result<Solution, Error> {
        self.solve_masked(&vec![true; self.n])
    }

    /// Number of equations added.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Residual sum of squares `|y − A c|²` of coefficients `c`, from the normal
    /// equations (`yᵀy − 2cᵀAᵀy + cᵀAᵀAc`).
    pub fn rss(&self, coef: &[f64]) -> f64 {
        let n = self.n;
        let mut q = 0.0;
        for i in 0..n {
            if coef[i] == 0.0 {
                continue;
            }
            q -= 2.0 * coef[i] * self.rhs[i];
            q += coef[i] * coef[i] * self.gram[i * n + i];
            for j in i + 1..n {
                q += 2.0 * coef[i] * coef[j] * self.gram[i * n + j];
            }
        }
        (self.yy + q).max(0.0)
    }

    /// As [`LeastSquares::solve`] but only columns with `allowed[i]` may enter.
    pub fn solve_masked(&self, allowed: &[bool]) -> Result<Solution, Error> {
        super::stop::check();
        let n = self.n;
        let g = |i: usize, j: usize| {
            if i <= j {
                self.gram[i * n + j]
            } else {
                self.gram[j * n + i]
            }
        };
        let scale: Vec<f64> = (0..n)
            .map(|i| {
                if g(i, i) > 0.0 {
                    1.0 / g(i, i).sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        let mut l = vec![0.0; n * n];
        let mut kept = vec![false; n];
        for k in 0..n {
            if scale[k] == 0.0 || !allowed[k] {
                continue;
            }
            let mut d = g(k, k) * scale[k] * scale[k];
            for j in 0..k {
                d -= l[k * n + j] * l[k * n + j];
            }
            if d < DEPENDENT {
                continue;
            }
            kept[k] = true;
            let lkk = d.sqrt();
            l[k * n + k] = lkk;
            for i in k + 1..n {
                if scale[i] == 0.0 || !allowed[i] {
                    continue;
                }
                let mut s = g(i, k) * scale[i] * scale[k];
                for j in 0..k {
                    s -= l[i * n + j] * l[k * n + j];
                }
                l[i * n + k] = s / lkk;
            }
        }
        // forward: L z = D b ; backward: Lᵀ w = z ; c = D w  (kept columns only)
        let mut z = vec![0.0; n];
        for i in (0..n).filter(|&i| kept[i]) {
            let mut s = self.rhs[i] * scale[i];
            for j in (0..i).filter(|&j| kept[j]) {
                s -= l[i * n + j] * z[j];
            }
            z[i] = s / l[i * n + i];
        }
        let mut w = vec![0.0; n];
        for i in (0..n).rev().filter(|&i| kept[i]) {
            let mut s = z[i];
            for j in (i + 1..n).filter(|&j| kept[j]) {
                s -= l[j * n + i] * w[j];
            }
            w[i] = s / l[i * n + i];
        }
        let coef: Vec<f64> = (0..n).map(|i| w[i] * scale[i]).collect();
        if coef.iter().any(|c| !c.is_finite()) {
            return Err(Error::NotFinite);
        }
        Ok(Solution { coef, kept })
    }
}

/// A penalised solution and the smoothing it used.
pub struct Smoothed {
    /// Coefficients and kept columns.
    pub solution: Solution,
    /// The chosen multiplier λ (on unit-norm columns).
    pub lambda: f64,
    /// Effective degrees of freedom `tr(H)`.
    pub edf: f64,
}

impl LeastSquares {
    /// Penalised least squares `min |y − A c|² + λ Σ_i w_i (c_i/s_i)²` on the columns
    /// [`LeastSquares::solve`] keeps (`s_i` scales column i to unit norm), with λ chosen
    /// from 0 and 1e-8…10 (30 steps) by generalised cross-validation
    /// `GCV(λ) = n·RSS / (n − tr H)²` (Craven & Wahba, Numer. Math. 31 (1979) 377).
    /// `weights` is 0 for unpenalised columns. Hand-written for the same reason as the
    /// solver: a 60-column dense problem, nalgebra's Cholesky does the algebra.
    pub fn solve_smoothed(&self, weights: &[f64]) -> Result<Smoothed, Error> {
        let base = self.solve()?;
        let idx: Vec<usize> = (0..self.n).filter(|&i| base.kept[i]).collect();
        let m = idx.len();
        let n = self.n;
        let g = |i: usize, j: usize| {
            if i <= j {
                self.gram[i * n + j]
            } else {
                self.gram[j * n + i]
            }
        };
        let scale: Vec<f64> = idx.iter().map(|&i| 1.0 / g(i, i).sqrt()).collect();
        let gs = DMatrix::from_fn(m, m, |a, b| g(idx[a], idx[b]) * scale[a] * scale[b]);
        let bs = DVector::from_fn(m, |a, _| self.rhs[idx[a]] * scale[a]);
        let rows = self.rows as f64;
        let mut best: Option<(f64, f64, f64, nalgebra::DVector<f64>)> = None;
        let lambdas =
            std::iter::once(0.0).chain((0..30).map(|k| 10f64.powf(-8.0 + 9.0 * k as f64 / 29.0)));
        for lambda in lambdas {
            let mut a = gs.clone();
            for (d, &i) in idx.iter().enumerate() {
                a[(d, d)] += lambda * weights[i];
            }
            let Some(ch) = a.cholesky() else { continue };
            let c = ch.solve(&bs);
            let rss = (self.yy - 2.0 * c.dot(&bs) + c.dot(&(&gs * &c))).max(0.0);
            let edf = ch.solve(&gs).trace();
            if edf >= rows {
                continue;
            }
            let gcv = rows * rss / ((rows - edf) * (rows - edf));
            if best.as_ref().is_none_or(|b| gcv < b.0) {
                best = Some((gcv, lambda, edf, c));
            }
        }
        let (_, lambda, edf, c) = best.ok_or(Error::Singular)?;
        let mut coef = vec![0.0; n];
        for (d, &i) in idx.iter().enumerate() {
            coef[i] = c[d] * scale[d];
        }
        if coef.iter().any(|c| !c.is_finite()) {
            return Err(Error::NotFinite);
        }
        Ok(Smoothed {
            solution: Solution {
                coef,
                kept: base.kept,
            },
            lambda,
            edf,
        })
    }
}

/// Weighted least squares `min Σ_i w_i (y_i − rows_i · c)²` with 0/1 weights `w` (rows with
/// `w_i > 0` enter) under the **truncated** rank policy: a column whose norm over the
/// entering rows is below 1e-9 of the largest gets coefficient 0 (instead of an arbitrary
/// huge value), the others are scaled to unit norm and solved by SVD with singular values
/// below 1e-9 of the largest dropped (the minimum-norm solution).
///
/// Formula: `c = V Σ⁺ Uᵀ b` on the scaled live columns (Golub & Van Loan, Matrix
/// Computations, 4th ed. 2013, §5.5.4). Returns all zeros when no row enters, no column is
/// live or the SVD fails.
/// Known bad cases: weights other than 0/1 are treated as 1 (rows are not scaled by √w).
pub fn truncated_svd(rows: &[Vec<f64>], y: &[f64], w: &[f64]) -> Vec<f64> {
    let p = rows.first().map_or(0, Vec::len);
    let idx: Vec<usize> = (0..y.len()).filter(|&i| w[i] > 0.0).collect();
    if p == 0 || idx.is_empty() {
        return vec![0.0; p];
    }
    let norms: Vec<f64> = (0..p)
        .map(|j| {
            idx.iter()
                .map(|&i| rows[i][j] * rows[i][j])
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    let biggest = norms.iter().fold(0.0f64, |a, &b| a.max(b));
    if biggest == 0.0 {
        return vec![0.0; p];
    }
    // a column the surface cannot excite (e.g. rotation about the axis of a surface of
    // revolution) gets coefficient 0 instead of an arbitrary huge value
    let live: Vec<bool> = norms.iter().map(|&v| v > 1e-9 * biggest).collect();
    let scale: Vec<f64> = norms
        .iter()
        .zip(&live)
        .map(|(&v, &l)| if l { v } else { 1.0 })
        .collect();
    let a = DMatrix::from_fn(idx.len(), p, |r, j| {
        if live[j] {
            rows[idx[r]][j] / scale[j]
        } else {
            0.0
        }
    });
    let b = DVector::from_iterator(idx.len(), idx.iter().map(|&i| y[i]));
    let svd = a.svd(true, true);
    let smax = svd.singular_values.max();
    match svd.solve(&b, smax * 1e-9) {
        Ok(x) => (0..p)
            .map(|j| if live[j] { x[j] / scale[j] } else { 0.0 })
            .collect(),
        Err(_) => vec![0.0; p],
    }
}

#[cfg(test)]
mod tests;
