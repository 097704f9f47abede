//! Analytic height-function surfaces `z = f(x, y)` (the Python study's test surfaces).

use serde::{Deserialize, Serialize};

use super::error::{Error, Result};

/// One term of `g(x, y)`; angles in radians, lengths in mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeightTerm {
    /// `a sin(kx x + px) cos(ky y + py)`; `[a, kx, px, ky, py]`.
    Sc([f64; 5]),
    /// `a exp(-((x - x0)^2 / (2 sx^2) + (y - y0)^2 / (2 sy^2)))`; `[a, x0, y0, sx, sy]`.
    Gauss([f64; 5]),
}

/// `z = scale * sum(terms) + offset` on `x in [0, lx]`, `y in [0, ly]` (mm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeightSurface {
    /// Extent in x, mm.
    pub lx: f64,
    /// Extent in y, mm.
    pub ly: f64,
    /// Multiplier S of the sum of terms.
    #[serde(default = "one")]
    pub scale: f64,
    /// Offset C, mm.
    #[serde(default)]
    pub offset: f64,
    /// The terms of g.
    pub terms: Vec<HeightTerm>,
}

fn one() -> f64 {
    1.0
}

/// Height and its first and second partial derivatives at a point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeightJet {
    /// f, mm.
    pub z: f64,
    /// df/dx.
    pub fx: f64,
    /// df/dy.
    pub fy: f64,
    /// d2f/dx2, 1/mm.
    pub fxx: f64,
}

impl HeightSurface {
    /// Checks extents > 0, at least one term and finite constants (Gaussian widths > 0).
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("lx (mm)", self.lx), ("ly (mm)", self.ly)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be finite and > 0",
                });
            }
        }
        if !(self.scale.is_finite() && self.offset.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "scale/offset",
                value: self.scale,
                reason: "must be finite",
            });
        }
        if self.terms.is_empty() {
            return Err(Error::TooFewPoints {
                what: "a height surface (terms)",
                min: 1,
                got: 0,
            });
        }
        for (index, t) in self.terms.iter().enumerate() {
            let (HeightTerm::Sc(c) | HeightTerm::Gauss(c)) = t;
            if c.iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    field: "terms",
                    index,
                });
            }
            if let HeightTerm::Gauss(c) = t
                && (c[3] <= 0.0 || c[4] <= 0.0)
            {
                return Err(Error::InvalidParameter {
                    name: "gauss sx/sy (mm)",
                    value: c[3].min(c[4]),
                    reason: "must be > 0",
                });
            }
        }
        Ok(())
    }

    /// `f`, `f_x`, `f_y`, `f_xx` at (x, y) (mm), analytically.
    pub fn jet(&self, x: f64, y: f64) -> HeightJet {
        let mut j = HeightJet::default();
        for t in &self.terms {
            match *t {
                HeightTerm::Sc([a, kx, px, ky, py]) => {
                    let (sx, cx) = (kx * x + px).sin_cos();
                    let (sy, cy) = (ky * y + py).sin_cos();
                    j.z += a * sx * cy;
                    j.fx += a * kx * cx * cy;
                    j.fy -= a * ky * sx * sy;
                    j.fxx -= a * kx * kx * sx * cy;
                }
                HeightTerm::Gauss([a, x0, y0, sx, sy]) => {
                    let (dx, dy) = (x - x0, y - y0);
                    let g = a * (-(dx * dx / (2.0 * sx * sx) + dy * dy / (2.0 * sy * sy))).exp();
                    j.z += g;
                    j.fx -= g * dx / (sx * sx);
                    j.fy -= g * dy / (sy * sy);
                    j.fxx += g * (dx * dx / (sx * sx) - 1.0) / (sx * sx);
                }
            }
        }
        j.z = self.scale * j.z + self.offset;
        j.fx *= self.scale;
        j.fy *= self.scale;
        j.fxx *= self.scale;
        j
    }

    /// Surface point `(x, y, f(x, y))` and outward unit normal `(-f_x, -f_y, 1)/|.|` (material
    /// below the surface).
    pub fn point_normal(&self, x: f64, y: f64) -> ([f64; 3], [f64; 3]) {
        let j = self.jet(x, y);
        let inv = 1.0 / (j.fx * j.fx + j.fy * j.fy + 1.0).sqrt();
        ([x, y, j.z], [-j.fx * inv, -j.fy * inv, inv])
    }

    /// The Python study's surfaces 1, 2, 3 (`tests/data/step/surfaces.json`: bounding
    /// boxes 120x140x38, 135x175x68.28, 150x150x54.02 mm like Zhang et al. 2023's Fig. 4). None
    /// otherwise.
    pub fn reference(id: u32) -> Option<Self> {
        use std::f64::consts::TAU;
        let (lx, ly, scale, offset, terms) = match id {
            1 => (
                120.0,
                140.0,
                17.08647059768471,
                19.234687045924023,
                vec![
                    HeightTerm::Sc([1.0, TAU / 115.0, 0.4, TAU / 135.0, 0.3]),
                    HeightTerm::Gauss([0.8, 45.0, 85.0, 21.0, 24.0]),
                    HeightTerm::Gauss([-0.7, 90.0, 35.0, 19.0, 22.0]),
                ],
            ),
            2 => (
                135.0,
                175.0,
                28.935073184945743,
                32.93381847033793,
                vec![
                    HeightTerm::Sc([1.0, TAU / 160.0, 0.2, TAU / 170.0, -0.5]),
                    HeightTerm::Sc([0.12, TAU / 75.0, 1.1, TAU / 80.0, 0.7]),
                    HeightTerm::Gauss([0.9, 40.0, 120.0, 33.0, 34.0]),
                    HeightTerm::Gauss([-0.6, 100.0, 60.0, 28.0, 30.0]),
                ],
            ),
            3 => (
                150.0,
                150.0,
                30.2325587654978,
                18.39627438291674,
                vec![
                    HeightTerm::Sc([0.8, TAU / 130.0, -0.6, TAU / 140.0, 0.9]),
                    HeightTerm::Gauss([1.0, 75.0, 75.0, 34.0, 34.0]),
                    HeightTerm::Gauss([-0.55, 30.0, 115.0, 21.0, 22.0]),
                    HeightTerm::Gauss([-0.55, 120.0, 35.0, 21.0, 22.0]),
                    HeightTerm::Gauss([0.4, 120.0, 120.0, 22.0, 22.0]),
                ],
            ),
            _ => return None,
        };
        Some(HeightSurface {
            lx,
            ly,
            scale,
            offset,
            terms,
        })
    }
}

#[cfg(test)]
mod tests;
