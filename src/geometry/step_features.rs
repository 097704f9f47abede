//! Network inputs describing a step-error segment (Zhang et al. 2023 Table 1), in the global frame
//! (the paper) or in a local frame of the segment (transfers across surfaces).

use serde::{Deserialize, Serialize};

use super::error::{Error, Result, check_points};
use super::spline::{CubicSpline3, Parameterization};
use crate::numeric::vec3::{add, cross, dot, normalize, scale, sub};

/// Coordinate frame of the input features.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeatureFrame {
    /// Machine coordinates, as Zhang et al. 2023 (Table 1): the network learns where the surface
    /// is.
    Global,
    /// Origin at the first CC point P_i, x along P_i -> P_{i+1}, z along the mean CL-CC normal
    /// made orthogonal to x, y = z x x: invariant to where the segment sits and how it turns.
    Local,
}

/// Layout of one segment's feature row: the m CC points (x, y, z each), the two CL points,
/// the tool radius, and optionally ("knot distances") the signed distances `L_j - R` of the m CC
/// points to the CL line (µm), their minimum and maximum (µm) and the normal curvature at the
/// middle from second differences (1/m, negative = convex). Other lengths in mm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct StepFeatures {
    /// Frame of the coordinates.
    pub frame: FeatureFrame,
    /// Number m of CC points fed to the network; curves with another count are resampled
    /// at m equal steps of a uniform-parameter spline.
    pub points: usize,
    /// Add `L_j - R` (µm) for each CC point j (the distances eq. 1 extremises), their min,
    /// max and the middle's normal curvature.
    pub knot_distances: bool,
    /// Two outputs, the signed one-sided errors `R - L_min` and `L_max - R` (µm), both smooth in
    /// the inputs; the convexity rule (sign of the middle's normal curvature from second
    /// differences) then picks one. One output (the step error itself, as Zhang et al. 2023)
    /// otherwise.
    #[serde(default)]
    pub two_sided: bool,
}

impl StepFeatures {
    /// Zhang et al. 2023's inputs: 20 CC points, 2 CL points and R in machine coordinates (67
    /// values).
    pub fn paper() -> Self {
        StepFeatures {
            frame: FeatureFrame::Global,
            points: 20,
            knot_distances: false,
            two_sided: false,
        }
    }

    /// Local-frame inputs with m = 20 points.
    pub fn local() -> Self {
        StepFeatures {
            frame: FeatureFrame::Local,
            points: 20,
            knot_distances: false,
            two_sided: false,
        }
    }

    /// Network outputs per segment: 2 when two-sided, else 1.
    pub fn n_outputs(&self) -> usize {
        if self.two_sided { 2 } else { 1 }
    }

    /// Training targets of one exactly solved segment (µm): `[error]`, or
    /// `[R - L_min, L_max - R]` when two-sided (the solver must compute both branches).
    pub fn targets(&self, e: &super::StepError) -> Vec<f64> {
        if self.two_sided {
            let (g, u) = if e.convex {
                (e.signed_mm, e.other_side_mm)
            } else {
                (e.other_side_mm, e.signed_mm)
            };
            vec![g * 1000.0, u * 1000.0]
        } else {
            vec![e.error_mm * 1000.0]
        }
    }

    /// Step errors (µm) from network outputs (row-major, [`StepFeatures::n_outputs`] per
    /// segment) and the convexity flags returned by [`StepFeatures::write`].
    pub fn combine(&self, outputs: &[f64], convex: &[bool]) -> Vec<f64> {
        if self.two_sided {
            outputs
                .chunks_exact(2)
                .zip(convex)
                .map(|(o, c)| if *c { o[0].abs() } else { o[1].abs() })
                .collect()
        } else {
            outputs.iter().map(|v| v.max(0.0)).collect()
        }
    }

    /// Values per segment: `3m + 6 + 1` (+ `m + 3` with knot distances).
    pub fn len(&self) -> usize {
        3 * self.points
            + 7
            + if self.knot_distances {
                self.points + 3
            } else {
                0
            }
    }

    /// Always false (a row has at least 16 values); for clippy's `len` convention.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Checks 3 <= m <= 1000.
    pub fn validate(&self) -> Result<()> {
        if !(3..=1000).contains(&self.points) {
            return Err(Error::InvalidParameter {
                name: "feature points (m)",
                value: self.points as f64,
                reason: "must be in 3..=1000",
            });
        }
        Ok(())
    }

    /// Writes the feature row of one segment into `out` (length [`StepFeatures::len`]) and
    /// returns its convexity (normal curvature at the middle from second differences < 0).
    /// `spline` is scratch space reused across calls (resampling only).
    /// Errors: fewer than 3 CC points, non-finite values, coincident CC ends.
    pub fn write(
        &self,
        tool_radius_mm: f64,
        cl: [[f64; 3]; 2],
        cc: &[[f64; 3]],
        spline: &mut CubicSpline3,
        out: &mut [f64],
    ) -> Result<bool> {
        let m = self.points;
        if out.len() != self.len() {
            return Err(Error::Shape {
                what: "feature row",
                expected: self.len(),
                got: out.len(),
            });
        }
        if cc.len() < 3 {
            return Err(Error::TooFewPoints {
                what: "the cc curve",
                min: 3,
                got: cc.len(),
            });
        }
        check_points("cl", &cl)?;
        check_points("cc", cc)?;
        let resampled;
        let pts: &[[f64; 3]] = if cc.len() == m {
            cc
        } else {
            spline.fit(cc, Parameterization::Uniform)?;
            resampled = (0..m)
                .map(|i| spline.eval(i as f64 / (m - 1) as f64))
                .collect::<Vec<_>>();
            &resampled
        };
        let origin = pts[0];
        let (ex, ey, ez) = match self.frame {
            FeatureFrame::Global => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]),
            FeatureFrame::Local => {
                let ex = normalize(sub(pts[m - 1], origin));
                if dot(ex, ex) == 0.0 {
                    return Err(Error::DuplicatePoints { index: 0 });
                }
                let nm = sub(cl[0], cc[0]);
                let nm = [
                    nm[0] + cl[1][0] - cc[cc.len() - 1][0],
                    nm[1] + cl[1][1] - cc[cc.len() - 1][1],
                    nm[2] + cl[1][2] - cc[cc.len() - 1][2],
                ];
                let mut ez = normalize(sub(nm, scale(ex, dot(nm, ex))));
                if dot(ez, ez) == 0.0 {
                    ez = [0.0, 0.0, 1.0];
                }
                (ex, cross(ez, ex), ez)
            }
        };
        let to_frame = |p: [f64; 3]| match self.frame {
            FeatureFrame::Global => p,
            FeatureFrame::Local => {
                let d = sub(p, origin);
                [dot(d, ex), dot(d, ey), dot(d, ez)]
            }
        };
        let mut i = 0;
        for p in pts.iter().chain(cl.iter()) {
            let q = to_frame(*p);
            out[i..i + 3].copy_from_slice(&q);
            i += 3;
        }
        out[i] = tool_radius_mm;
        i += 1;
        // Normal curvature at the middle from second differences (1/mm): its sign is the
        // convexity rule of eq. (1).
        let nm = normalize(sub(add(cl[0], cl[1]), add(cc[0], cc[cc.len() - 1])));
        let h = crate::numeric::vec3::norm(sub(pts[m - 1], pts[0])) / (m - 1) as f64;
        let j = (m - 1) / 2;
        let second = |k: usize| dot(sub(add(pts[k - 1], pts[k + 1]), scale(pts[k], 2.0)), nm);
        let kappa = if m % 2 == 0 {
            0.5 * (second(j) + second(j + 1))
        } else {
            second(j)
        } / (h * h);
        if self.knot_distances {
            let d = sub(cl[1], cl[0]);
            let len2 = dot(d, d);
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for p in pts {
                let c = cross(sub(*p, cl[0]), d);
                let v = ((dot(c, c) / len2).sqrt() - tool_radius_mm) * 1000.0;
                (lo, hi) = (lo.min(v), hi.max(v));
                out[i] = v;
                i += 1;
            }
            out[i] = lo;
            out[i + 1] = hi;
            out[i + 2] = kappa * 1000.0;
        }
        Ok(kappa < 0.0)
    }

    /// Feature matrix (row-major, `n x len()`) of `n` segments given as `(cl, cc)` pairs, and
    /// their convexity flags. Errors name the first bad segment ([`Error::InSegment`]).
    pub fn matrix<'a>(
        &self,
        tool_radius_mm: f64,
        segments: impl ExactSizeIterator<Item = ([[f64; 3]; 2], &'a [[f64; 3]])>,
    ) -> Result<(Vec<f64>, Vec<bool>)> {
        self.validate()?;
        let w = self.len();
        let mut out = vec![0.0; segments.len() * w];
        let mut convex = Vec::with_capacity(segments.len());
        let mut sp = CubicSpline3::new();
        for (index, ((cl, cc), row)) in segments.zip(out.chunks_exact_mut(w)).enumerate() {
            let c = self
                .write(tool_radius_mm, cl, cc, &mut sp, row)
                .map_err(|e| Error::InSegment {
                    index,
                    source: Box::new(e),
                })?;
            convex.push(c);
        }
        Ok((out, convex))
    }
}

#[cfg(test)]
mod tests;
