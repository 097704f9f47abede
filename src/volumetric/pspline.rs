//! Tensor-product cubic smoothing spline (P-spline) over the working volume, for the
//! hybrid model's residual.
//!
//! Written here rather than taken from a crate: the Rust spline crates checked
//! (DESIGN.md's table) interpolate 1-D or gridded data; none smooths scattered 3-D
//! data with a chosen penalty. The system is small (at most 6·6·6 coefficients), so a
//! dense Cholesky from nalgebra is enough.

use super::Error;
use super::data::{Bounds, VolumetricData};
use crate::numeric::bspline::uniform_cubic;
use crate::numeric::penalty::difference_penalty;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A smooth vector field `r(p) = Σ_ijk c_ijk B_i(x) B_j(y) B_k(z)` (mm) with uniform
/// cubic B-splines `B` on the fitted box.
///
/// Fit: penalised least squares (Eilers & Marx, Statist. Sci. 11 (1996) 89, "Flexible
/// smoothing with B-splines and penalties", §2 and §8 for tensor products):
/// `min Σ_n |r_n − r(p_n)|² + λ cᵀ(D₂ᵀD₂⊗I⊗I + I⊗D₂ᵀD₂⊗I + I⊗I⊗D₂ᵀD₂)c` with `D₂` the
/// second-difference matrix per axis, λ chosen by generalised cross-validation (Craven &
/// Wahba 1979) over a log grid, one λ for the three components. λ → ∞ leaves the
/// trilinear polynomial (the penalty's null space), λ → 0 the unpenalised spline.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SmoothingSpline3 {
    /// Box the basis spans (mm); points outside are clamped to it.
    pub range: [[f64; 2]; 3],
    /// Polynomial pieces per axis (basis functions = pieces + 3).
    pub pieces: [usize; 3],
    /// Coefficients (mm), index `(i·ny + j)·nz + k` with `n* = pieces + 3`.
    pub coef: Vec<[f64; 3]>,
    /// Smoothing parameter chosen by GCV (relative to `tr(BᵀB)/tr(P)`).
    pub lambda: f64,
    /// Effective degrees of freedom per component, `tr(H)`.
    pub effective_parameters: f64,
}

fn kron(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    a.kronecker(b)
}

/// Pieces per axis for a node set with `levels` distinct positions: one piece per two
/// node spacings, 1 to 3 — enough for smooth deformation (sag, thermal bend), few
/// enough that the spline stores fewer numbers than the grid it was fitted on.
pub fn default_pieces(levels: usize) -> usize {
    ((levels.saturating_sub(1)) / 2).clamp(1, 3)
}

impl SmoothingSpline3 {
    /// Fits the spline to `data` (nodes in mm, errors = values to smooth, mm) with
    /// `pieces` polynomial pieces per axis; λ by GCV. See the type's documentation.
    ///
    /// Known bad cases: fewer nodes than basis functions leave the fit to the penalty
    /// (GCV then picks a large λ, i.e. close to trilinear); nodes on one plane make the
    /// penalty's null space unidentifiable along the missing axis — the tiny ridge keeps
    /// the system solvable and the spline constant along it.
    pub fn fit(data: &VolumetricData, pieces: [usize; 3]) -> Result<SmoothingSpline3, Error> {
        let bounds = data.validate(1)?;
        if pieces.iter().any(|&p| p == 0 || p > 8) {
            return Err(Error::InvalidOption {
                name: "pieces",
                reason: "must be between 1 and 8 per axis".into(),
            });
        }
        let range = [0, 1, 2].map(|k| [bounds.min[k], bounds.max[k]]);
        let nb = pieces.map(|p| p + 3);
        let m = nb[0] * nb[1] * nb[2];
        let mut gram = DMatrix::<f64>::zeros(m, m);
        let mut rhs = DMatrix::<f64>::zeros(m, 3);
        let mut idx = Vec::with_capacity(64);
        let mut val = Vec::with_capacity(64);
        let mut yy = 0.0;
        for (p, e) in data.nodes.iter().zip(&data.errors) {
            Self::row(&range, &pieces, *p, &mut idx, &mut val);
            for (a, &ia) in idx.iter().enumerate() {
                for (b, &ib) in idx.iter().enumerate() {
                    gram[(ia, ib)] += val[a] * val[b];
                }
                for j in 0..3 {
                    rhs[(ia, j)] += val[a] * e[j];
                }
            }
            yy += e.iter().map(|v| v * v).sum::<f64>();
        }
        let eye = |n: usize| DMatrix::<f64>::identity(n, n);
        let pen = kron(
            &kron(&difference_penalty(nb[0], 2), &eye(nb[1])),
            &eye(nb[2]),
        ) + kron(
            &kron(&eye(nb[0]), &difference_penalty(nb[1], 2)),
            &eye(nb[2]),
        ) + kron(
            &kron(&eye(nb[0]), &eye(nb[1])),
            &difference_penalty(nb[2], 2),
        );
        let scale = gram.trace() / pen.trace().max(f64::MIN_POSITIVE);
        let ridge = 1e-9 * gram.trace() / m as f64;
        let n_obs = data.nodes.len() as f64;
        let mut best: Option<(f64, f64, DMatrix<f64>, f64)> = None;
        for step in 0..=24 {
            crate::numeric::stop::check();
            let lambda = 10f64.powf(-6.0 + step as f64 / 2.0);
            let a = &gram + &pen * (lambda * scale) + DMatrix::identity(m, m) * ridge;
            let Some(chol) = a.cholesky() else { continue };
            let c = chol.solve(&rhs);
            let edf = chol.solve(&gram).trace();
            // RSS = yᵀy − 2cᵀBᵀy + cᵀBᵀBc, summed over the three components
            let bc = &gram * &c;
            let rss = (yy - 2.0 * c.dot(&rhs) + c.dot(&bc)).max(0.0);
            let denom = (1.0 - edf / n_obs).max(1e-6);
            let gcv = rss / n_obs / (denom * denom);
            if best.as_ref().is_none_or(|b| gcv < b.0) {
                best = Some((gcv, lambda, c, edf));
            }
        }
        let (_, lambda, c, edf) = best.ok_or_else(|| Error::InvalidOption {
            name: "pieces",
            reason: "the smoothing system could not be solved for any λ".into(),
        })?;
        let coef = (0..m).map(|i| [c[(i, 0)], c[(i, 1)], c[(i, 2)]]).collect();
        Ok(SmoothingSpline3 {
            range,
            pieces,
            coef,
            lambda,
            effective_parameters: edf,
        })
    }

    /// Indices and values of the 64 basis products that are nonzero at `p`.
    fn row(
        range: &[[f64; 2]; 3],
        pieces: &[usize; 3],
        p: [f64; 3],
        idx: &mut Vec<usize>,
        val: &mut Vec<f64>,
    ) {
        let nb = pieces.map(|q| q + 3);
        let bx = uniform_cubic(p[0], range[0], pieces[0]);
        let by = uniform_cubic(p[1], range[1], pieces[1]);
        let bz = uniform_cubic(p[2], range[2], pieces[2]);
        idx.clear();
        val.clear();
        for (a, &va) in bx.1.iter().enumerate() {
            for (b, &vb) in by.1.iter().enumerate() {
                for (c, &vc) in bz.1.iter().enumerate() {
                    idx.push(((bx.0 + a) * nb[1] + by.0 + b) * nb[2] + bz.0 + c);
                    val.push(va * vb * vc);
                }
            }
        }
    }

    /// The smoothed field (mm) at `p` (mm); coordinates outside the box are clamped.
    pub fn eval(&self, p: [f64; 3]) -> [f64; 3] {
        let mut idx = Vec::with_capacity(64);
        let mut val = Vec::with_capacity(64);
        Self::row(&self.range, &self.pieces, p, &mut idx, &mut val);
        let mut out = [0.0; 3];
        for (&i, &v) in idx.iter().zip(&val) {
            for (o, c) in out.iter_mut().zip(&self.coef[i]) {
                *o += v * c;
            }
        }
        out
    }

    /// Numbers the spline stores (three per coefficient).
    pub fn parameter_count(&self) -> usize {
        3 * self.coef.len()
    }

    /// The fitted box (mm).
    pub fn bounds(&self) -> Bounds {
        Bounds {
            min: self.range.map(|r| r[0]),
            max: self.range.map(|r| r[1]),
        }
    }

    /// Rejects a stored spline whose coefficient count does not match its pieces.
    pub fn check(&self) -> Result<(), Error> {
        let nb: usize = self.pieces.iter().map(|p| p + 3).product();
        if self.coef.len() != nb || self.pieces.contains(&0) {
            return Err(Error::InvalidOption {
                name: "spline",
                reason: "stored coefficients do not match the spline's pieces".into(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
