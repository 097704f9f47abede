//! Exact step error of 3-axis ball-end finishing between two cutter locations (seed 000, eq. 1).

use serde::{Deserialize, Serialize};

use super::brent;
use super::error::{Error, Result, check_points};
use super::spline::{CubicSpline3, Parameterization};
use super::vec3::{cross, dot, norm, normalize, scale, sub};

/// One step of a tool path: two ball centres (CL points) and the cutter-contact curve between
/// their contact points, as points in feed order, first and last included (mm).
/// `cl[0] = cc[0] + R n0`, `cl[1] = cc[m-1] + R n1` with n the outward unit surface normals.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepErrorSegment {
    /// The two ball centres, mm.
    pub cl: [[f64; 3]; 2],
    /// Points of the CC curve (m >= 3), mm.
    pub cc: Vec<[f64; 3]>,
}

/// The step error of one segment and how it was found.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepError {
    /// `e = |R - L|`, mm (eq. 1).
    pub error_mm: f64,
    /// `L`: distance from the extremal CC point `p^e` to the CL line, mm.
    pub distance_mm: f64,
    /// Spline parameter of `p^e` in [0, 1].
    pub t: f64,
    /// `p^e`, mm.
    pub point: [f64; 3],
    /// True when the CC curve is convex at the segment's middle (L minimised), false when
    /// concave or flat (L maximised).
    pub convex: bool,
    /// True when the curve's normal curvature changes sign inside the segment (an inflection):
    /// the convexity rule then follows the middle only, and `other_side_mm` matters.
    pub inflection: bool,
    /// The signed one-sided error of the chosen branch: `R - L_min` (convex) or `L_max - R`
    /// (concave), mm; `error_mm = |signed_mm|`.
    pub signed_mm: f64,
    /// The signed one-sided error of the other branch (`L_max - R` for convex, `R - L_min` for
    /// concave), mm; computed for inflected segments, and for all with
    /// [`StepErrorSolver::both_branches`] (NaN otherwise).
    pub other_side_mm: f64,
}

/// Reusable solver (keeps its spline buffers, so batches do not allocate per segment).
#[derive(Clone, Debug)]
pub struct StepErrorSolver {
    spline: CubicSpline3,
    param: Parameterization,
    both: bool,
}

impl Default for StepErrorSolver {
    fn default() -> Self {
        Self::new(Parameterization::Uniform)
    }
}

/// Tolerance of the Brent search on the spline parameter: the value error is then about
/// |d2L/dt2| * 1e-12 / 2 mm (|d2L/dt2| < 1 mm on any sane step), far below 1e-6 um = 1e-9 mm.
const TOL_T: f64 = 1e-6;

impl StepErrorSolver {
    /// A solver using `param` to place the CC points on the spline parameter axis
    /// (`Uniform` for equal-parameter samples, as the seed's iso-parametric paths).
    pub fn new(param: Parameterization) -> Self {
        StepErrorSolver {
            spline: CubicSpline3::new(),
            param,
            both: false,
        }
    }

    /// Also computes the other branch's one-sided error for every segment (twice the work;
    /// labels for the two-sided network).
    pub fn both_branches(mut self, yes: bool) -> Self {
        self.both = yes;
        self
    }

    /// Exact step error of one segment (seed 000, eq. 1):
    /// `e = |R - L|`, `L = |P_i^CL p^e x P_i^CL P_{i+1}^CL| / |P_i^CL P_{i+1}^CL|`, where the CC
    /// curve is the not-a-knot cubic spline through `cc` and `p^e` is its point of minimum
    /// distance to the CL line when the curve is convex, maximum when concave. Convexity is the
    /// sign of `Q''(1/2) · n_mid` (curvature relative to the mean outward normal
    /// `n_mid = (n0 + n1)/|n0 + n1|`, `n = (cl - cc)/R`): negative = convex.
    /// The extremum: best CC point, then Brent's search on the two spline pieces around it
    /// (to |Δt| < 1e-6, i.e. a value error far below 1e-6 um), ends included.
    ///
    /// Units: mm in, mm out. Reference: seed 000 eq. (1) and Fig. 1.
    /// Known bad cases: inflected segments (flagged; the middle decides), CC points so sparse
    /// that the spline misses the curve's shape, several equal extrema (one is returned).
    /// Errors: R <= 0, m < 3, non-finite points, cl[0] == cl[1], |cl - cc| != R (> 0.1 %).
    pub fn solve(
        &mut self,
        tool_radius_mm: f64,
        cl: [[f64; 3]; 2],
        cc: &[[f64; 3]],
    ) -> Result<StepError> {
        let r = tool_radius_mm;
        if !(r.is_finite() && r > 0.0) {
            return Err(Error::InvalidParameter {
                name: "tool_radius (mm)",
                value: r,
                reason: "must be finite and > 0",
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
        let a = cl[0];
        let d = sub(cl[1], a);
        let len = norm(d);
        if len.is_nan() || len <= 1e-12 * r {
            return Err(Error::ZeroLengthStep);
        }
        let u = scale(d, 1.0 / len);
        let last = cc.len() - 1;
        let (r0, r1) = (sub(cl[0], cc[0]), sub(cl[1], cc[last]));
        for (end, v) in [(0usize, r0), (1, r1)] {
            let dist = norm(v);
            if (dist - r).abs() > 1e-3 * r + 1e-9 {
                return Err(Error::InconsistentRadius {
                    end,
                    distance_mm: dist,
                    tool_radius_mm: r,
                });
            }
        }
        let n_mid = normalize([r0[0] + r1[0], r0[1] + r1[1], r0[2] + r1[2]]);
        self.spline.fit(cc, self.param)?;
        let sp = &self.spline;
        let kappa_mid = dot(sp.eval_d2(0.5), n_mid);
        let convex = kappa_mid < 0.0;
        let inflection = sp.knot_d2().iter().any(|m| {
            let s = dot(*m, n_mid);
            (s < 0.0) != convex && s != 0.0
        });
        // Squared distance to the CL line: monotone in L, so the same extremum, no sqrt.
        let dist2 = |q: [f64; 3]| {
            let c = cross(sub(q, a), u);
            dot(c, c)
        };
        let (best, other) = if inflection || self.both {
            (
                extremum(sp, &dist2, convex),
                Some(extremum(sp, &dist2, !convex)),
            )
        } else {
            (extremum(sp, &dist2, convex), None)
        };
        let l = best.1.sqrt();
        let one_sided = |l: f64, convex: bool| if convex { r - l } else { l - r };
        let other_side_mm = other.map_or(f64::NAN, |(_, d2)| one_sided(d2.sqrt(), !convex));
        Ok(StepError {
            error_mm: (r - l).abs(),
            signed_mm: one_sided(l, convex),
            distance_mm: l,
            t: best.0,
            point: sp.eval(best.0),
            convex,
            inflection,
            other_side_mm,
        })
    }
}

/// (t, squared distance) of the minimum (`minimize`) or maximum distance on the spline.
fn extremum(sp: &CubicSpline3, dist2: &impl Fn([f64; 3]) -> f64, minimize: bool) -> (f64, f64) {
    let sign = if minimize { 1.0 } else { -1.0 };
    let pts = sp.points();
    let knots = sp.knots();
    let (mut kbest, mut gbest) = (0usize, f64::INFINITY);
    for (k, p) in pts.iter().enumerate() {
        let g = sign * dist2(*p);
        if g < gbest {
            (kbest, gbest) = (k, g);
        }
    }
    let m = pts.len();
    let (lo, hi) = (
        knots[kbest.saturating_sub(1)],
        knots[(kbest + 1).min(m - 1)],
    );
    let mut best = (knots[kbest], gbest);
    let (t, g) = brent::minimize(|t| sign * dist2(sp.eval(t)), lo, hi, TOL_T, 100);
    if g < best.1 {
        best = (t, g);
    }
    (best.0, sign * best.1)
}

/// Exact step error of one segment with a fresh solver (uniform parameterization).
/// See [`StepErrorSolver::solve`].
pub fn step_error(tool_radius_mm: f64, segment: &StepErrorSegment) -> Result<StepError> {
    StepErrorSolver::default().solve(tool_radius_mm, segment.cl, &segment.cc)
}

/// Exact step errors of a batch of segments, split over up to `threads` threads (0 = all
/// cores). Errors name the first bad segment's index ([`Error::InSegment`]).
pub fn step_errors(
    tool_radius_mm: f64,
    segments: &[StepErrorSegment],
    threads: usize,
) -> Result<Vec<StepError>> {
    let threads = if threads == 0 {
        std::thread::available_parallelism()
            .map(|t| t.get())
            .unwrap_or(1)
    } else {
        threads
    };
    let per = segments.len().div_ceil(threads.max(1)).max(1024);
    let run = |offset: usize, segs: &[StepErrorSegment]| -> Result<Vec<StepError>> {
        let mut solver = StepErrorSolver::default();
        segs.iter()
            .enumerate()
            .map(|(i, s)| {
                solver
                    .solve(tool_radius_mm, s.cl, &s.cc)
                    .map_err(|e| Error::InSegment {
                        index: offset + i,
                        source: Box::new(e),
                    })
            })
            .collect()
    };
    if segments.len() <= per {
        return run(0, segments);
    }
    let parts: Vec<Result<Vec<StepError>>> = std::thread::scope(|s| {
        let handles: Vec<_> = segments
            .chunks(per)
            .enumerate()
            .map(|(c, chunk)| s.spawn(move || run(c * per, chunk)))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("step-error worker panicked"))
            .collect()
    });
    let mut out = Vec::with_capacity(segments.len());
    for p in parts {
        out.extend(p?);
    }
    Ok(out)
}
