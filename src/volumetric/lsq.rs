//! Linear least squares that drops columns the data cannot identify.

use super::Error;

/// Least-squares solution of `A c ≈ y` accumulated row by row.
///
/// Columns are taken in the caller's order; a column that is (numerically) a linear
/// combination of earlier kept columns is dropped and its coefficient fixed to 0. This
/// is what makes the ISO 230-1 fit well defined: with one tool offset the Z-axis
/// angular errors only act through that offset and are indistinguishable from Z
/// straightness, so they come after the translational columns and are dropped.
/// Hand-written (normal equations + ordered Cholesky with skipped pivots, ~60 lines)
/// because nalgebra has no rank-revealing solver that respects a given column order.
pub(crate) struct LeastSquares {
    n: usize,
    gram: Vec<f64>,
    rhs: Vec<f64>,
    yy: f64,
    rows: usize,
}

/// A solved system: coefficients (0 for dropped columns) and which columns were kept.
pub(crate) struct Solution {
    pub coef: Vec<f64>,
    pub kept: Vec<bool>,
}

/// A column whose part not explained by earlier columns has less than this share of
/// its squared norm is treated as dependent.
const DEPENDENT: f64 = 1e-9;

impl LeastSquares {
    pub(crate) fn new(n: usize) -> Self {
        LeastSquares {
            n,
            gram: vec![0.0; n * n],
            rhs: vec![0.0; n],
            yy: 0.0,
            rows: 0,
        }
    }

    /// Adds one equation `row · c ≈ y` (row given sparsely as (column, value) pairs).
    pub(crate) fn add(&mut self, row: &[(usize, f64)], y: f64) {
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
    pub(crate) fn solve(&self) -> Result<Solution, Error> {
        self.solve_masked(&vec![true; self.n])
    }

    /// Number of equations added.
    pub(crate) fn rows(&self) -> usize {
        self.rows
    }

    /// Residual sum of squares `|y − A c|²` of coefficients `c`, from the normal
    /// equations (`yᵀy − 2cᵀAᵀy + cᵀAᵀAc`).
    pub(crate) fn rss(&self, coef: &[f64]) -> f64 {
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
    pub(crate) fn solve_masked(&self, allowed: &[bool]) -> Result<Solution, Error> {
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
            return Err(Error::Fit("least-squares solution is not finite".into()));
        }
        Ok(Solution { coef, kept })
    }
}

/// A penalised solution and the smoothing it used.
pub(crate) struct Smoothed {
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
    pub(crate) fn solve_smoothed(&self, weights: &[f64]) -> Result<Smoothed, Error> {
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
        let gs = nalgebra::DMatrix::from_fn(m, m, |a, b| g(idx[a], idx[b]) * scale[a] * scale[b]);
        let bs = nalgebra::DVector::from_fn(m, |a, _| self.rhs[idx[a]] * scale[a]);
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
        let (_, lambda, edf, c) =
            best.ok_or_else(|| Error::Fit("penalised normal equations are singular".into()))?;
        let mut coef = vec![0.0; n];
        for (d, &i) in idx.iter().enumerate() {
            coef[i] = c[d] * scale[d];
        }
        if coef.iter().any(|c| !c.is_finite()) {
            return Err(Error::Fit("least-squares solution is not finite".into()));
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

#[cfg(test)]
mod tests {
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
        assert!(
            (s.coef[0] - 2.0).abs() < 1e-10 && (s.coef[1] - 3.0).abs() < 1e-10 && s.coef[2] == 0.0
        );
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
}
