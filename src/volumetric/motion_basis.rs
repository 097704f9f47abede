//! Bases for the ISO 230-1 error motions along one axis, in the normalised position
//! s ∈ [−1, 1]: function 0 is the constant, 1 the line s, 2..=cap the curved terms that
//! the fit penalises.
//!
//! - `legendre`: P_0..P_cap (maps written before session 3 use it);
//! - `spline` (default for new fits): cubic regression splines on cap − 2 equal pieces in
//!   Demmler-Reinsch form — the basis of the spline space that is orthonormal in L²[−1, 1]
//!   and diagonalises the roughness ∫ f''² ds (Demmler & Reinsch 1975, Numer. Math. 24;
//!   Ruppert, Wand & Carroll 2003, §3.7), so the curved terms are ordered by roughness and
//!   their penalty weights are their roughness. Same count as the polynomial of degree cap,
//!   but local: a global polynomial of degree 5 swings most at the ends of travel, where a
//!   spline does not (measured: `cargo bench --bench volumetric`, BENCHMARKS.md).
//!   With cap ≤ 3 the spline space is the cubic polynomials and the Legendre basis is used.
//!
//! Written here: the basis is 60 lines of nalgebra on top of [`crate::numeric::bspline`].

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::sync::OnceLock;

/// Which basis a kinematic model's error-motion coefficients refer to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionBasis {
    /// Legendre polynomials P_0..P_cap (maps written before session 3).
    #[default]
    Legendre,
    /// Cubic regression splines in Demmler-Reinsch form (default for new fits).
    Spline,
}

/// Highest cap with a precomputed spline basis (the fit's degree limit).
const MAX_CAP: usize = 8;

/// The Demmler-Reinsch functions of one cap: B-spline coefficients (p × (cap − 1), columns
/// for terms 2..=cap) and their roughness relative to term 2.
struct SplineTerms {
    pieces: usize,
    coef: DMatrix<f64>,
    weight: Vec<f64>,
}

fn spline_terms(cap: usize) -> &'static SplineTerms {
    static TERMS: OnceLock<Vec<SplineTerms>> = OnceLock::new();
    &TERMS.get_or_init(|| (4..=MAX_CAP).map(build).collect())[cap - 4]
}

/// Builds the basis for `cap` (4 ≤ cap ≤ 8) by quadrature on 801 points.
fn build(cap: usize) -> SplineTerms {
    let p = cap + 1;
    let pieces = p - 3;
    let g = 801;
    let ds = 2.0 / (g - 1) as f64;
    let scale2 = (pieces as f64 / 2.0).powi(2); // (dt/ds)²
    let mut gram = DMatrix::<f64>::zeros(p, p);
    let mut rough = DMatrix::<f64>::zeros(p, p);
    for i in 0..g {
        let s = -1.0 + i as f64 * ds;
        let w = if i == 0 || i == g - 1 { 0.5 * ds } else { ds };
        let (j, v) = crate::numeric::bspline::uniform_cubic(s, [-1.0, 1.0], pieces);
        let t = (s + 1.0) / 2.0 * pieces as f64 - j as f64;
        let d2 = [1.0 - t, 3.0 * t - 2.0, 1.0 - 3.0 * t, t].map(|x| x * scale2);
        for a in 0..4 {
            for b in 0..4 {
                gram[(j + a, j + b)] += w * v[a] * v[b];
                rough[(j + a, j + b)] += w * d2[a] * d2[b];
            }
        }
    }
    let l = gram
        .cholesky()
        .expect("B-spline Gram matrix is positive definite")
        .l();
    let l_inv = l.try_inverse().expect("Cholesky factor is invertible");
    let c = &l_inv * &rough * l_inv.transpose();
    let c = (&c + c.transpose()) * 0.5;
    let eig = c.symmetric_eigen();
    let mut order: Vec<usize> = (0..p).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    // the two smallest (≈ 0) are the constant and the line: the fit has those as 1 and s
    let curved = &order[2..];
    let mut coef = DMatrix::<f64>::zeros(p, curved.len());
    for (col, &k) in curved.iter().enumerate() {
        let v = l_inv.transpose() * eig.eigenvectors.column(k);
        // sign: positive at s = 1 (deterministic across platforms' eigen solvers)
        let end: f64 = v[p - 3] / 6.0 + v[p - 2] * 4.0 / 6.0 + v[p - 1] / 6.0;
        let sign = if end < 0.0 { -1.0 } else { 1.0 };
        coef.set_column(col, &(v * sign));
    }
    let first = eig.eigenvalues[curved[0]];
    let weight = curved.iter().map(|&k| eig.eigenvalues[k] / first).collect();
    SplineTerms {
        pieces,
        coef,
        weight,
    }
}

/// Legendre polynomials `P_0..=P_n` at `s` (Bonnet's recursion).
fn legendre(s: f64, n: usize, out: &mut Vec<f64>) {
    out.clear();
    out.push(1.0);
    if n >= 1 {
        out.push(s);
    }
    for k in 1..n {
        let p = ((2 * k + 1) as f64 * s * out[k] - k as f64 * out[k - 1]) / (k + 1) as f64;
        out.push(p);
    }
}

impl MotionBasis {
    /// The spline basis only differs from the polynomials from cap 4 on.
    fn uses_splines(self, cap: usize) -> bool {
        self == MotionBasis::Spline && (4..=MAX_CAP).contains(&cap)
    }

    /// Values of terms 0..=cap at `s` ∈ [−1, 1] (clamped), into `out` (dimensionless).
    pub fn values(self, s: f64, cap: usize, out: &mut Vec<f64>) {
        let s = s.clamp(-1.0, 1.0);
        if !self.uses_splines(cap) {
            legendre(s, cap, out);
            return;
        }
        let terms = spline_terms(cap);
        let (j, v) = crate::numeric::bspline::uniform_cubic(s, [-1.0, 1.0], terms.pieces);
        out.clear();
        out.push(1.0);
        out.push(s);
        for col in 0..terms.coef.ncols() {
            out.push((0..4).map(|a| v[a] * terms.coef[(j + a, col)]).sum());
        }
    }

    /// Penalty weight of term `d` (≥ 2) relative to term 2: the roughness ratio
    /// ∫f_d''²/∫f_2''² for splines; ((d(d+1))/6)² for Legendre (P_d is an eigenfunction of
    /// the Legendre operator with eigenvalue d(d+1), which plays the role of roughness).
    pub fn weight(self, cap: usize, d: usize) -> f64 {
        if d < 2 {
            return 0.0;
        }
        if self.uses_splines(cap) {
            spline_terms(cap).weight[d - 2]
        } else {
            ((d * (d + 1)) as f64 / 6.0).powi(2)
        }
    }
}

#[cfg(test)]
mod tests;
