//! A measurement's deviations as a 2-D field (nu × nv, point k = iv·nu + iu): the flattening
//! orders the 1-D methods can use, and a genuinely 2-D penalised smoother.

use super::error::{Error, check_signal};
use super::whittaker::{Smoothed, half_power_frequency, minimise_log_lambda, whittaker};
use crate::numeric::penalty::difference_penalty;
use nalgebra::{DMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};

/// How a grid is read by the decomposition.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Order {
    /// Row by row, u fastest (Chen et al. 2024's reading; a jump at every row end).
    RowMajor,
    /// Row by row with every odd row reversed, so consecutive samples stay neighbours.
    Serpentine,
    /// The field as a field: 2-D penalised smoothing (default).
    #[default]
    #[serde(rename = "2d", alias = "two_d")]
    TwoD,
}

/// Largest grid side for the exact 2-D eigen-solution (O(side³)); larger grids fall back to
/// the serpentine 1-D treatment.
pub const MAX_SIDE_2D: usize = 1200;

/// Reorders grid samples (k = iv·nu + iu) into the 1-D order used by the decomposition.
pub fn flatten(x: &[f64], nu: usize, nv: usize, order: Order) -> Vec<f64> {
    match order {
        Order::Serpentine => (0..nv)
            .flat_map(|iv| {
                let row = &x[iv * nu..(iv + 1) * nu];
                let rev = iv % 2 == 1;
                (0..nu).map(move |iu| if rev { row[nu - 1 - iu] } else { row[iu] })
            })
            .collect(),
        _ => x.to_vec(),
    }
}

/// Inverse of [`flatten`].
pub fn unflatten(y: &[f64], nu: usize, nv: usize, order: Order) -> Vec<f64> {
    // Serpentine is its own inverse.
    flatten(y, nu, nv, order)
}

/// Checks that nu·nv matches the sample count.
pub fn check_grid(n: usize, nu: usize, nv: usize) -> Result<(), Error> {
    if nu == 0 || nv == 0 || nu.checked_mul(nv) != Some(n) {
        return Err(Error::GridMismatch { nu, nv, n });
    }
    Ok(())
}

/// Dense d-th difference penalty DᵀD (side × side) and its eigen-decomposition.
fn penalty_eigen(side: usize, d: usize) -> (Vec<f64>, DMatrix<f64>) {
    if side <= d {
        return (vec![0.0; side], DMatrix::identity(side, side));
    }
    let p = difference_penalty(side, d);
    let eig = SymmetricEigen::new(p);
    (
        eig.eigenvalues.iter().map(|v| v.max(0.0)).collect(),
        eig.eigenvectors,
    )
}

/// 2-D Whittaker smoother on an nu × nv grid: Z minimising
/// ‖X − Z‖² + λ(‖D_u Z‖² + ‖Z D_vᵀ‖²) (d-th differences along u and along v, one λ: grid
/// steps are treated as equal in both directions), solved exactly in the tensor eigenbasis
/// of the two 1-D penalties, Z = Q_v [(Q_vᵀ X Q_u) ⊘ (1 + λ(w_u,j + w_v,i))] Q_uᵀ, with λ by
/// GCV computed in that basis (exact trace). O(nu³ + nv³ + nu·nv·(nu + nv)).
///
/// Reference: Eilers, Currie & Durbán 2006 (Comput. Stat. Data Anal. 50, tensor penalties);
/// Craven & Wahba 1979 (GCV). Natural ends on all four edges.
/// Units: those of x. Known bad cases: a side > [`MAX_SIDE_2D`] (caller falls back);
/// a single row or column (treated as 1-D).
pub fn whittaker_2d(
    x: &[f64],
    nu: usize,
    nv: usize,
    d: usize,
    lambda: Option<f64>,
) -> Result<Smoothed, Error> {
    check_signal("2-D smoothing", x, 1)?;
    check_grid(x.len(), nu, nv)?;
    if nu == 1 || nv == 1 {
        return whittaker(x, d, lambda);
    }
    if !(1..=6).contains(&d) {
        return Err(Error::BadParam {
            name: "smoothing_order",
            reason: "must be between 1 and 6 (difference order of the penalty)".into(),
        });
    }
    let (wu, qu) = penalty_eigen(nu, d);
    let (wv, qv) = penalty_eigen(nv, d);
    // X as nv × nu (row iv, column iu).
    let xm = DMatrix::from_row_slice(nv, nu, x);
    let y = qv.transpose() * &xm * &qu;
    let n = x.len() as f64;
    let gcv = |p: f64| {
        let lam = 10f64.powf(p);
        let (mut rss, mut tr) = (0.0, 0.0);
        for j in 0..nu {
            for i in 0..nv {
                let g = 1.0 / (1.0 + lam * (wu[j] + wv[i]));
                let r = (1.0 - g) * y[(i, j)];
                rss += r * r;
                tr += g;
            }
        }
        let denom = 1.0 - tr / n;
        if denom <= 1e-12 {
            f64::INFINITY
        } else {
            rss / n / (denom * denom)
        }
    };
    let lam = match lambda {
        Some(l) if l.is_finite() && l >= 0.0 => l,
        Some(_) => {
            return Err(Error::BadParam {
                name: "lambda",
                reason: "must be a finite number >= 0".into(),
            });
        }
        None => 10f64.powf(minimise_log_lambda(-4.0, 12.0, gcv)),
    };
    let mut g = y.clone();
    let mut edf = 0.0;
    for j in 0..nu {
        for i in 0..nv {
            let gij = 1.0 / (1.0 + lam * (wu[j] + wv[i]));
            g[(i, j)] *= gij;
            edf += gij;
        }
    }
    let z = &qv * g * qu.transpose();
    let mut signal = Vec::with_capacity(x.len());
    for i in 0..nv {
        for j in 0..nu {
            signal.push(z[(i, j)]);
        }
    }
    Ok(Smoothed {
        signal,
        lambda: lam,
        edf,
        cutoff: half_power_frequency(lam, d),
    })
}

#[cfg(test)]
mod tests;
