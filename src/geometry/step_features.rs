//! Network inputs describing a step-error segment: Zhang et al. 2023's coordinates (Table 1), in
//! the global frame (the paper) or a local frame of the segment, or the scale-free distance
//! profile that transfers to surfaces no one trained on (the default since model version 2).

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

/// What the network reads of a segment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StepInputs {
    /// The m CC points and the two CL points in [`StepFeatures::frame`], the tool radius, and
    /// optionally the knot distances (mm and µm as they come): what models of metadata version 1
    /// read, and the default when a stored model names no inputs.
    #[default]
    Coordinates,
    /// The distance profile: `d_j = L_j - R` (eq. 1's distances of m points of the CC spline to
    /// the CL line) divided by their largest magnitude `s`, then the smallest and largest `d_j
    /// / s`; the two outputs are what the m samples miss of each one-sided error, also divided
    /// by `s` (see [`StepFeatures::targets`]). Nothing in it depends on where the part sits,
    /// how it is turned, how high it is, or (to first order) on the tool radius and the step
    /// length: a step error is a sagitta, and its shape along the segment, once divided by its
    /// size, looks alike on every smooth surface. Coordinates do not have that property: a
    /// network fed millimetres learns the training surface's ranges of step length, radius
    /// and height, and extrapolates outside them.
    Profile,
}

/// Per-segment values a feature row needs back when its network outputs are turned into a step
/// error ([`StepFeatures::combine`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RowInfo {
    /// The convexity rule of eq. 1: the CC spline's curvature at its middle along the mean
    /// outward normal is negative (L minimised), as the exact solver decides it (profile
    /// inputs), or from second differences of the m points (coordinate inputs).
    pub convex: bool,
    /// Profile inputs: the scale `s = max |d_j|`, µm (at least [`PROFILE_FLOOR_UM`]); 0 with
    /// coordinate inputs.
    pub scale_um: f64,
    /// Smallest `d_j = L_j - R` over the m points, µm (profile inputs; 0 otherwise).
    pub d_min_um: f64,
    /// Largest `d_j`, µm (profile inputs; 0 otherwise).
    pub d_max_um: f64,
    /// Most the continuous curve can reach beyond the samples' extremes, µm: a quarter of the
    /// largest second difference `|d_{j-1} - 2 d_j + d_{j+1}|` (a parabola misses at most an
    /// eighth of it between samples; twice that for margin). Profile inputs; 0 otherwise.
    pub miss_bound_um: f64,
}

/// Smallest profile scale `s`, µm: a segment whose m distances all lie within 1e-6 µm of R is
/// flat to far below anything the network resolves.
pub const PROFILE_FLOOR_UM: f64 = 1e-6;

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
    /// What the network reads ([`StepInputs::Coordinates`] when absent: models of metadata
    /// version 1). With [`StepInputs::Profile`], `frame` and `knot_distances` are not used and
    /// the outputs are always two.
    #[serde(default)]
    pub inputs: StepInputs,
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
            inputs: StepInputs::Coordinates,
        }
    }

    /// Local-frame coordinates with m = 20 points.
    pub fn local() -> Self {
        StepFeatures {
            frame: FeatureFrame::Local,
            points: 20,
            knot_distances: false,
            two_sided: false,
            inputs: StepInputs::Coordinates,
        }
    }

    /// The default of new networks: the distance profile at m = 20 points, two outputs
    /// (see [`StepInputs::Profile`] for why it transfers).
    pub fn profile() -> Self {
        StepFeatures {
            frame: FeatureFrame::Local,
            points: 20,
            knot_distances: false,
            two_sided: true,
            inputs: StepInputs::Profile,
        }
    }

    /// Network outputs per segment: 2 when two-sided or profile inputs, else 1.
    pub fn n_outputs(&self) -> usize {
        if self.two_sided || self.inputs == StepInputs::Profile {
            2
        } else {
            1
        }
    }

    /// Training targets of one exactly solved segment whose row reported `info`: `[error]`
    /// (µm), or `[R - L_min, L_max - R]` (µm) when two-sided (the solver must compute both
    /// branches). Profile inputs: `[(R - L_min + d_min) / s, (L_max - R - d_max) / s]`, what the
    /// continuous curve adds to the m samples' extremes (>= 0), in units of `s`.
    pub fn targets(&self, e: &super::StepError, info: &RowInfo) -> Vec<f64> {
        let (g, u) = if e.convex {
            (e.signed_mm, e.other_side_mm)
        } else {
            (e.other_side_mm, e.signed_mm)
        };
        let (g, u) = (g * 1000.0, u * 1000.0);
        match self.inputs {
            StepInputs::Profile => vec![
                (g + info.d_min_um) / info.scale_um,
                (u - info.d_max_um) / info.scale_um,
            ],
            StepInputs::Coordinates if self.two_sided => vec![g, u],
            StepInputs::Coordinates => vec![e.error_mm * 1000.0],
        }
    }

    /// Step errors (µm) from network outputs (row-major, [`StepFeatures::n_outputs`] per
    /// segment) and the rows' [`RowInfo`]. Profile inputs: `|s c_0 - d_min|` when convex,
    /// `|d_max + s c_1|` when concave, where `c_k` is the output clipped to
    /// `[0, miss_bound / s]`: the continuous curve reaches at least the samples' extremes and at
    /// most [`RowInfo::miss_bound_um`] beyond them, so a network asked about a shape it never
    /// saw cannot answer outside what the geometry allows.
    pub fn combine(&self, outputs: &[f64], info: &[RowInfo]) -> Vec<f64> {
        match self.inputs {
            StepInputs::Profile => outputs
                .chunks_exact(2)
                .zip(info)
                .map(|(o, i)| {
                    let hi = i.miss_bound_um / i.scale_um;
                    if i.convex {
                        (i.scale_um * o[0].clamp(0.0, hi) - i.d_min_um).abs()
                    } else {
                        (i.d_max_um + i.scale_um * o[1].clamp(0.0, hi)).abs()
                    }
                })
                .collect(),
            StepInputs::Coordinates if self.two_sided => outputs
                .chunks_exact(2)
                .zip(info)
                .map(|(o, i)| if i.convex { o[0].abs() } else { o[1].abs() })
                .collect(),
            StepInputs::Coordinates => outputs.iter().map(|v| v.max(0.0)).collect(),
        }
    }

    /// The step errors (µm) the m samples alone give (the extreme `d_j` picked by the
    /// convexity rule, no network): the baseline the profile network improves on.
    pub fn knot_estimate(info: &[RowInfo]) -> Vec<f64> {
        info.iter()
            .map(|i| if i.convex { -i.d_min_um } else { i.d_max_um }.abs())
            .collect()
    }

    /// Values per segment: profile `m + 2`; coordinates `3m + 6 + 1` (+ `m + 3` with knot
    /// distances).
    pub fn len(&self) -> usize {
        if self.inputs == StepInputs::Profile {
            return self.points + 2;
        }
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
    /// returns what [`StepFeatures::combine`] needs of it ([`RowInfo`]). `spline` is scratch
    /// space reused across calls.
    /// Errors: fewer than 3 CC points, non-finite values, coincident CC ends.
    pub fn write(
        &self,
        tool_radius_mm: f64,
        cl: [[f64; 3]; 2],
        cc: &[[f64; 3]],
        spline: &mut CubicSpline3,
        out: &mut [f64],
    ) -> Result<RowInfo> {
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
        if self.inputs == StepInputs::Profile {
            return profile_row(tool_radius_mm, cl, cc, m, spline, out);
        }
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
        Ok(RowInfo {
            convex: kappa < 0.0,
            ..RowInfo::default()
        })
    }

    /// Feature matrix (row-major, `n x len()`) of `n` segments given as `(cl, cc)` pairs, and
    /// their [`RowInfo`]s. Errors name the first bad segment ([`Error::InSegment`]).
    pub fn matrix<'a>(
        &self,
        tool_radius_mm: f64,
        segments: impl ExactSizeIterator<Item = ([[f64; 3]; 2], &'a [[f64; 3]])>,
    ) -> Result<(Vec<f64>, Vec<RowInfo>)> {
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

/// The profile row ([`StepInputs::Profile`]): the not-a-knot spline through `cc` (uniform
/// parameter, as the exact solver), m points on it at `t = j / (m - 1)`, their distances
/// `d_j = |(Q(t_j) - CL_0) x u| - R` to the CL line (µm, u its unit direction), `s = max |d_j|`
/// (at least [`PROFILE_FLOOR_UM`]), the row `d_0/s .. d_{m-1}/s, min d_j/s, max d_j/s`, and the
/// convexity rule of the exact solver (`Q''(1/2) . n_mid < 0`, `n_mid` the mean of the two
/// outward normals `(CL - CC)/R`). Reference: Zhang et al. 2023 eq. 1.
fn profile_row(
    r: f64,
    cl: [[f64; 3]; 2],
    cc: &[[f64; 3]],
    m: usize,
    spline: &mut CubicSpline3,
    out: &mut [f64],
) -> Result<RowInfo> {
    let d = sub(cl[1], cl[0]);
    let len = crate::numeric::vec3::norm(d);
    if len.is_nan() || len <= 1e-12 * r {
        return Err(Error::ZeroLengthStep);
    }
    let u = scale(d, 1.0 / len);
    spline.fit(cc, Parameterization::Uniform)?;
    let n_mid = normalize(add(sub(cl[0], cc[0]), sub(cl[1], cc[cc.len() - 1])));
    let convex = dot(spline.eval_d2(0.5), n_mid) < 0.0;
    let (mut lo, mut hi, mut s) = (f64::INFINITY, f64::NEG_INFINITY, PROFILE_FLOOR_UM);
    for (j, o) in out[..m].iter_mut().enumerate() {
        let q = sub(spline.eval(j as f64 / (m - 1) as f64), cl[0]);
        let w = cross(q, u);
        let v = (dot(w, w).sqrt() - r) * 1000.0;
        (lo, hi, s) = (lo.min(v), hi.max(v), s.max(v.abs()));
        *o = v;
    }
    let dd = out[..m]
        .windows(3)
        .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
        .fold(0.0, f64::max);
    for o in &mut out[..m] {
        *o /= s;
    }
    out[m] = lo / s;
    out[m + 1] = hi / s;
    Ok(RowInfo {
        convex,
        scale_um: s,
        d_min_um: lo,
        d_max_um: hi,
        miss_bound_um: dd / 4.0,
    })
}

#[cfg(test)]
mod tests;
