//! Sample generation: iso-parametric tool paths over a surface, cut into step-error segments.

use serde::{Deserialize, Serialize};

use super::error::{Error, Result, check_points};
use super::height_surface::HeightSurface;
use super::spline::{CubicSpline3, Parameterization};
use super::step_error::StepErrorSegment;
use crate::numeric::vec3::{add, norm, normalize, scale, sub};

/// Most segments one plan may generate (memory guard: ~0.5 kB per segment).
pub const MAX_SEGMENTS: usize = 2_000_000;

/// How to lay iso-parametric paths over a surface. Give either `lines` or `step_over_mm`, and
/// either `points_per_line` or `cl_spacing_mm`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PathPlan {
    /// Ball radius R, mm.
    pub tool_radius_mm: f64,
    /// Distance between neighbouring paths, mm (in the parameter plane: y for a height
    /// surface; along the v grid direction, rounded to whole grid rows, for a grid).
    #[serde(default)]
    pub step_over_mm: Option<f64>,
    /// Distance between CL points along a path, mm (in the parameter plane, see above).
    #[serde(default)]
    pub cl_spacing_mm: Option<f64>,
    /// Number of paths (overrides `step_over_mm`).
    #[serde(default)]
    pub lines: Option<usize>,
    /// CL points per path (overrides `cl_spacing_mm`).
    #[serde(default)]
    pub points_per_line: Option<usize>,
    /// Points per CC curve, ends included (Zhang et al. 2023's m; 20 in the study).
    #[serde(default = "default_m")]
    pub cc_points: usize,
}

fn default_m() -> usize {
    20
}

impl PathPlan {
    /// The study's plan: 200 lines x 100 CL points, m = 20, R = 5 mm (19,800 segments).
    pub fn study() -> Self {
        PathPlan {
            tool_radius_mm: 5.0,
            step_over_mm: None,
            cl_spacing_mm: None,
            lines: Some(200),
            points_per_line: Some(100),
            cc_points: 20,
        }
    }

    fn counts(&self, extent_across: f64, extent_along: f64) -> Result<(usize, usize)> {
        let r = self.tool_radius_mm;
        if !(r.is_finite() && r > 0.0) {
            return Err(Error::InvalidParameter {
                name: "tool_radius_mm",
                value: r,
                reason: "must be finite and > 0",
            });
        }
        if self.cc_points < 3 || self.cc_points > 1000 {
            return Err(Error::InvalidParameter {
                name: "cc_points",
                value: self.cc_points as f64,
                reason: "must be in 3..=1000",
            });
        }
        let count = |explicit: Option<usize>,
                     spacing: Option<f64>,
                     extent: f64,
                     name: &'static str,
                     min: usize| {
            match (explicit, spacing) {
                (Some(n), _) if n >= min => Ok(n),
                (Some(n), _) => Err(Error::InvalidParameter {
                    name,
                    value: n as f64,
                    reason: "too few (lines >= 1, points >= 2)",
                }),
                (None, Some(s)) if s.is_finite() && s > 0.0 => {
                    Ok(((extent / s).round() as usize + 1).max(min))
                }
                (None, Some(s)) => Err(Error::InvalidParameter {
                    name,
                    value: s,
                    reason: "spacing must be finite and > 0",
                }),
                (None, None) => Err(Error::InvalidParameter {
                    name,
                    value: f64::NAN,
                    reason: "give lines or step_over_mm, and points_per_line or cl_spacing_mm",
                }),
            }
        };
        let lines = count(
            self.lines,
            self.step_over_mm,
            extent_across,
            "lines / step_over_mm",
            1,
        )?;
        let pts = count(
            self.points_per_line,
            self.cl_spacing_mm,
            extent_along,
            "points_per_line / cl_spacing_mm",
            2,
        )?;
        let total = lines.saturating_mul(pts - 1);
        if total > MAX_SEGMENTS {
            return Err(Error::InvalidParameter {
                name: "segments (lines x (points_per_line - 1))",
                value: total as f64,
                reason: "at most 2,000,000: raise step_over_mm or cl_spacing_mm",
            });
        }
        Ok((lines, pts))
    }
}

/// Segments of iso-parametric paths along x over a height surface: line k at
/// `y = k/(lines-1) * ly` (one line: `ly/2`), CL points at `x_j = j/(pts-1) * lx`, CC points
/// at `x = x_j + (x_{j+1} - x_j) t`, `t = 0, 1/(m-1), .., 1`, and `CL = P + R n`.
/// Order: line-major (`index = k * (pts - 1) + j`), as in the Python study.
///
/// Reference: `tests/data/step/README.md` "Tool paths / samples" (the Python study); Zhang et al.
/// 2023 "Sample construction" (200 lines x 100 CL points).
pub fn height_surface_segments(
    surface: &HeightSurface,
    plan: &PathPlan,
) -> Result<Vec<StepErrorSegment>> {
    surface.validate()?;
    function_segments(
        surface.lx,
        surface.ly,
        |x, y| surface.point_normal(x, y),
        plan,
    )
}

/// [`height_surface_segments`] over any height function: `point_normal(x, y)` gives the surface
/// point and its outward unit normal at (x, y) in `[0, lx] x [0, ly]` (mm). Same paths, order
/// and CL placement.
pub fn function_segments(
    lx: f64,
    ly: f64,
    point_normal: impl Fn(f64, f64) -> ([f64; 3], [f64; 3]),
    plan: &PathPlan,
) -> Result<Vec<StepErrorSegment>> {
    let (lines, pts) = plan.counts(ly, lx)?;
    let (r, m) = (plan.tool_radius_mm, plan.cc_points);
    let mut out = Vec::with_capacity(lines * (pts - 1));
    for k in 0..lines {
        let y = if lines == 1 {
            0.5 * ly
        } else {
            k as f64 / (lines - 1) as f64 * ly
        };
        for j in 0..pts - 1 {
            let x0 = j as f64 / (pts - 1) as f64 * lx;
            let x1 = (j + 1) as f64 / (pts - 1) as f64 * lx;
            let mut cc = Vec::with_capacity(m);
            let mut normals = [[0.0; 3]; 2];
            for i in 0..m {
                let t = i as f64 / (m - 1) as f64;
                let (p, n) = point_normal(x0 + (x1 - x0) * t, y);
                if i == 0 {
                    normals[0] = n;
                }
                if i == m - 1 {
                    normals[1] = n;
                }
                cc.push(p);
            }
            let cl = [
                add(cc[0], scale(normals[0], r)),
                add(cc[m - 1], scale(normals[1], r)),
            ];
            out.push(StepErrorSegment { cl, cc });
        }
    }
    Ok(out)
}

/// Segments of iso-parametric paths along the u direction of a nominal grid (the surfaces of
/// openapi.yaml: `nu x nv` points and unit outward normals, `k = iv * nu + iu`). Paths follow grid
/// rows `iv = 0, s, 2s, ..` with `s` the step-over in whole rows; along a row the points and
/// normals are interpolated by not-a-knot cubic splines (uniform in u), CL points are placed at
/// equal u steps and `CL = P + R n` with the interpolated normal renormalised.
/// Known bad case: a coarse grid (few points per curvature radius) gives smooth-but-wrong
/// curves between grid points; the step errors are then those of the interpolated surface.
pub fn grid_segments(
    nu: usize,
    nv: usize,
    points: &[[f64; 3]],
    normals: &[[f64; 3]],
    plan: &PathPlan,
) -> Result<Vec<StepErrorSegment>> {
    if nu < 3 || nv < 1 {
        return Err(Error::TooFewPoints {
            what: "a grid row (nu)",
            min: 3,
            got: nu,
        });
    }
    if points.len() != nu * nv || normals.len() != nu * nv {
        return Err(Error::Shape {
            what: "grid points/normals (nu*nv)",
            expected: nu * nv,
            got: points.len().min(normals.len()),
        });
    }
    check_points("points", points)?;
    check_points("normals", normals)?;
    if let Some(index) = normals.iter().position(|n| norm(*n) < 1e-9) {
        return Err(Error::InvalidParameter {
            name: "normal length",
            value: index as f64,
            reason: "normals must be unit vectors",
        });
    }
    let row_len = |iv: usize| {
        (1..nu)
            .map(|i| norm(sub(points[iv * nu + i], points[iv * nu + i - 1])))
            .sum::<f64>()
    };
    let along = (0..nv).map(row_len).sum::<f64>() / nv as f64;
    let across = if nv > 1 {
        (0..nv - 1)
            .map(|iv| {
                norm(sub(
                    points[(iv + 1) * nu + nu / 2],
                    points[iv * nu + nu / 2],
                ))
            })
            .sum::<f64>()
    } else {
        0.0
    };
    // Step-over in whole rows: s rows ≈ step_over / mean row spacing.
    let row_step = if nv > 1 {
        across / (nv - 1) as f64
    } else {
        1.0
    };
    let mut plan_rows = plan.clone();
    if plan.lines.is_none()
        && let Some(so) = plan.step_over_mm
        && so.is_finite()
        && so > 0.0
    {
        let s = (so / row_step).round().max(1.0) as usize;
        plan_rows.lines = Some((nv - 1) / s + 1);
    }
    let (lines, pts) = plan_rows.counts(across, along)?;
    let lines = lines.min(nv);
    let stride = if lines > 1 { (nv - 1) / (lines - 1) } else { 0 };
    let (r, m) = (plan.tool_radius_mm, plan.cc_points);
    let mut ps = CubicSpline3::new();
    let mut ns = CubicSpline3::new();
    let mut out = Vec::with_capacity(lines * (pts - 1));
    for line in 0..lines {
        let iv = if lines == 1 { nv / 2 } else { line * stride };
        ps.fit(&points[iv * nu..(iv + 1) * nu], Parameterization::Uniform)?;
        ns.fit(&normals[iv * nu..(iv + 1) * nu], Parameterization::Uniform)?;
        for j in 0..pts - 1 {
            let (u0, u1) = (
                j as f64 / (pts - 1) as f64,
                (j + 1) as f64 / (pts - 1) as f64,
            );
            let cc: Vec<[f64; 3]> = (0..m)
                .map(|i| ps.eval(u0 + (u1 - u0) * i as f64 / (m - 1) as f64))
                .collect();
            let n0 = normalize(ns.eval(u0));
            let n1 = normalize(ns.eval(u1));
            let cl = [add(cc[0], scale(n0, r)), add(cc[m - 1], scale(n1, r))];
            out.push(StepErrorSegment { cl, cc });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
