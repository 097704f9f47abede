//! The reconstructed compensated surface: a smooth surface through the compensated grid
//! points, resampled at any density, with compensated ball-end cutter-location points.
//!
//! Choice: a tensor-product C² cubic spline that *interpolates* the compensated points
//! (not-a-knot ends), over the uniform grid parameters u = iu/(nu−1), v = iv/(nv−1).
//! Interpolation rather than least-squares or thin-plate smoothing because the offsets are
//! already the smoothed systematic error of the decomposition (GCV-tuned) and the nominal
//! points are exact CAD samples: smoothing again would only bias the surface and would break
//! the contract that the grid points themselves are reproduced. Offsets and normals are
//! interpolated the same way (normals re-normalised), so CL' = CL − offset·n can be formed at
//! any sample: for a ball-end tool of radius R, CL = CC + R·n, so moving the contact point by
//! −offset·n moves the ball centre by the same vector.

use super::error::Error;
use super::offsets::{check_values, check_vectors, compensate_points};
use crate::signal::spline::CubicSpline;
use serde::Serialize;

/// A compensated surface on an nu × nv grid (point k = iv·nu + iu).
#[derive(Clone, Debug)]
pub struct CompensatedSurface {
    nu: usize,
    nv: usize,
    /// Seven fields per grid point: x', y', z' (compensated), i, j, k (normal), offset.
    fields: [Vec<f64>; 7],
}

/// Points, normals, offsets (and CL points when a tool radius is given) on a regular grid.
#[derive(Clone, Debug, Serialize)]
pub struct CompensatedGrid {
    /// Grid points along u.
    pub nu: usize,
    /// Grid points along v.
    pub nv: usize,
    /// Compensated points x', y', z' (mm), u fastest, `nu * nv` of them.
    pub points: Vec<[f64; 3]>,
    /// Unit outer normals at the points.
    pub normals: Vec<[f64; 3]>,
    /// Signed offset applied along the normal at each point, mm.
    pub offsets: Vec<f64>,
    /// Cutter-location points (mm): each point moved out by the tool radius along its
    /// normal; present only when a tool radius was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cl: Option<Vec<[f64; 3]>>,
}

/// Largest resampling side accepted.
pub const MAX_SIDE: usize = 2000;

fn uniform(n: usize) -> Vec<f64> {
    (0..n).map(|i| i as f64 / (n - 1) as f64).collect()
}

/// Interpolates an nv × nu field (row-major, u fastest) at new parameters (u fastest).
fn resample_field(f: &[f64], nu: usize, nv: usize, us: &[f64], vs: &[f64]) -> Vec<f64> {
    let (gu, gv) = (uniform(nu), uniform(nv));
    // Along u, row by row.
    let mut rows = vec![0.0; nv * us.len()];
    for iv in 0..nv {
        let s = CubicSpline::not_a_knot(&gu, &f[iv * nu..(iv + 1) * nu]).expect("uniform knots");
        for (j, &u) in us.iter().enumerate() {
            rows[iv * us.len() + j] = s.eval(u);
        }
    }
    // Along v, column by column.
    let mut out = vec![0.0; vs.len() * us.len()];
    let mut col = vec![0.0; nv];
    for j in 0..us.len() {
        for iv in 0..nv {
            col[iv] = rows[iv * us.len() + j];
        }
        let s = CubicSpline::not_a_knot(&gv, &col).expect("uniform knots");
        for (i, &v) in vs.iter().enumerate() {
            out[i * us.len() + j] = s.eval(v);
        }
    }
    out
}

impl CompensatedSurface {
    /// Builds the surface from the nominal grid, its outward unit normals and the offsets
    /// (systematic error, mm, positive where material was left).
    ///
    /// Formula: p'_k = p_k − offset_k·n_k ([`compensate_points`]), then tensor-product
    /// not-a-knot cubic interpolation of p', n and offset over (u, v) ∈ \[0,1\]².
    /// Errors: nu or nv < 2, lengths ≠ nu·nv, non-finite values, zero normals.
    pub fn new(
        nu: usize,
        nv: usize,
        points: &[[f64; 3]],
        normals: &[[f64; 3]],
        offsets: &[f64],
    ) -> Result<Self, Error> {
        for (field, got) in [("nu", nu), ("nv", nv)] {
            if got < 2 {
                return Err(Error::BadSize {
                    field,
                    got,
                    reason: "a surface grid needs at least 2 points each way",
                });
            }
        }
        let n = nu * nv;
        check_vectors("points", points, n)?;
        check_vectors("normals", normals, n)?;
        check_values("offsets", offsets, n)?;
        let comp = compensate_points(points, normals, offsets)?;
        let col = |v: &[[f64; 3]], c: usize| v.iter().map(|p| p[c]).collect::<Vec<f64>>();
        Ok(Self {
            nu,
            nv,
            fields: [
                col(&comp, 0),
                col(&comp, 1),
                col(&comp, 2),
                col(normals, 0),
                col(normals, 1),
                col(normals, 2),
                offsets.to_vec(),
            ],
        })
    }

    /// The compensated surface sampled on a new nu2 × nv2 grid (same parameter range), with
    /// compensated ball-end CL points CL' = p' + R·n when `tool_radius` R (mm) is given.
    /// At nu2 = nu, nv2 = nv the original compensated points are returned (to rounding).
    /// Errors: a side < 2 or > [`MAX_SIDE`], negative or non-finite radius.
    pub fn resample(
        &self,
        nu2: usize,
        nv2: usize,
        tool_radius: Option<f64>,
    ) -> Result<CompensatedGrid, Error> {
        for (field, got) in [("nu", nu2), ("nv", nv2)] {
            if !(2..=MAX_SIDE).contains(&got) {
                return Err(Error::BadSize {
                    field,
                    got,
                    reason: "resampling density must be between 2 and 2000 per direction",
                });
            }
        }
        if let Some(r) = tool_radius {
            if !(r.is_finite() && r >= 0.0) {
                return Err(Error::BadToolRadius);
            }
        }
        let (us, vs) = (uniform(nu2), uniform(nv2));
        let f: Vec<Vec<f64>> = self
            .fields
            .iter()
            .map(|fl| resample_field(fl, self.nu, self.nv, &us, &vs))
            .collect();
        let m = nu2 * nv2;
        let points: Vec<[f64; 3]> = (0..m).map(|k| [f[0][k], f[1][k], f[2][k]]).collect();
        let normals: Vec<[f64; 3]> = (0..m)
            .map(|k| {
                let (a, b, c) = (f[3][k], f[4][k], f[5][k]);
                let len = (a * a + b * b + c * c).sqrt().max(1e-300);
                [a / len, b / len, c / len]
            })
            .collect();
        let cl = tool_radius.map(|r| {
            points
                .iter()
                .zip(&normals)
                .map(|(p, nrm)| [p[0] + r * nrm[0], p[1] + r * nrm[1], p[2] + r * nrm[2]])
                .collect()
        });
        Ok(CompensatedGrid {
            nu: nu2,
            nv: nv2,
            points,
            normals,
            offsets: f[6].clone(),
            cl,
        })
    }
}

#[cfg(test)]
mod tests;
