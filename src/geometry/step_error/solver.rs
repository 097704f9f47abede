//! The exact step-error solver: spline through the CC points, safeguarded Halley on each
//! piece's distance polynomial, batches and their thread split (Zhang et al. 2023 eq. 1).

use serde::{Deserialize, Serialize};

use super::lanes;

use crate::geometry::error::{Error, Result, check_points};
use crate::geometry::spline::{CubicSpline3, Parameterization};
use crate::numeric::vec3::{cross, dot, norm, normalize, scale, sub};
use crate::numeric::{brent, parallel};

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
    /// Squared distances of the knots to the CL line, mm^2.
    knot_dist2: Vec<f64>,
    /// Uniform knots, m >= 4: one segment, or [`BATCH_LANES`] at once (see `lanes.rs`).
    one: lanes::Lanes<1>,
    many: lanes::Lanes<BATCH_LANES>,
    /// Thomas factors of the uniform spline system, `f_0 = 1/4`, `f_i = 1/(4 - f_{i-1})`.
    factors: Vec<f64>,
    param: Parameterization,
    both: bool,
}

/// A segment as the batch entry point takes it: the two CL points and the CC points, mm.
pub type SegmentRef<'a> = ([[f64; 3]; 2], &'a [[f64; 3]]);

/// Segments solved side by side by [`StepErrorSolver::solve_batch`].
pub(super) const BATCH_LANES: usize = 4;

/// A validated segment: the CL line's point and unit direction, the mean outward normal, the
/// CC points.
#[derive(Clone, Copy)]
pub(super) struct Prepared<'a> {
    pub(super) a: [f64; 3],
    pub(super) u: [f64; 3],
    pub(super) n_mid: [f64; 3],
    pub(super) cc: &'a [[f64; 3]],
}

impl Default for StepErrorSolver {
    fn default() -> Self {
        Self::new(Parameterization::Uniform)
    }
}

/// Stops of the safeguarded Halley iteration on a piece's local parameter `b` (`t = t_k + b h_k`).
/// A bisection step or the bracket below 1e-6: |Δb| < 1e-6, a value error (|d2L/db2| Δb^2 / 2,
/// |d2L/db2| < 1 mm) far below 1e-6 um = 1e-9 mm.
pub(super) const TOL_B: f64 = 1e-6;
/// A Halley step below 1e-4: the iterate it leads to is then good to ~K 1e-12 (cubic
/// convergence, K = O(1) for these quintics), again far below the value tolerance.
pub(super) const TOL_HALLEY: f64 = 1e-4;

/// Tolerance of the Brent fallback on `b` (pieces where the slope does not bracket a root): the
/// value error is then about |d2L/db2| * 1e-12 / 2 mm, far below 1e-6 um.
pub(super) const TOL_BRENT: f64 = 1e-6;

impl StepErrorSolver {
    /// A solver using `param` to place the CC points on the spline parameter axis
    /// (`Uniform` for equal-parameter samples, as Zhang et al. 2023's iso-parametric paths).
    pub fn new(param: Parameterization) -> Self {
        StepErrorSolver {
            spline: CubicSpline3::new(),
            knot_dist2: Vec::new(),
            one: Default::default(),
            many: Default::default(),
            factors: Vec::new(),
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

    /// Exact step error of one segment (Zhang et al. 2023 eq. 1):
    /// `e = |R - L|`, `L = |P_i^CL p^e x P_i^CL P_{i+1}^CL| / |P_i^CL P_{i+1}^CL|`, where the CC
    /// curve is the not-a-knot cubic spline through `cc` and `p^e` is its point of minimum
    /// distance to the CL line when the curve is convex, maximum when concave. Convexity is the
    /// sign of `Q''(1/2) · n_mid` (curvature relative to the mean outward normal
    /// `n_mid = (n0 + n1)/|n0 + n1|`, `n = (cl - cc)/R`): negative = convex.
    ///
    /// The extremum: the best CC point (knot), then the stationary point of the squared
    /// distance on the spline piece next to it where the distance improves. On a piece the
    /// part of `Q(b) - P_i^CL` normal to the CL line is a cubic `P(b)`, so `L^2 = |P|^2` is a
    /// degree-6 polynomial and its stationary points are the roots of the quintic
    /// `g(b) = P(b) · P'(b)`; the root bracketed on the piece is found by Halley's method
    /// (`g' = |P'|^2 + P · P''`, `g''`) from the secant root, safeguarded by bisection, to
    /// |Δb| far below 1e-6 (a value error far below 1e-6 um; see `TOL_B`, `TOL_HALLEY`; a test
    /// checks 1e-12 mm against an exhaustive search). Pieces whose ends do not bracket a root
    /// (two stationary points on one piece) fall back to Brent's search. The knots, ends
    /// included, are candidates too. Uniform knots with m >= 4 take the lane code
    /// (`step_error/lanes.rs`, one lane here, four in [`StepErrorSolver::solve_batch`]).
    ///
    /// Units: mm in, mm out. Reference: Zhang et al. 2023 eq. 1 and Fig. 1.
    /// Known bad cases: inflected segments (flagged; the middle decides), CC points so sparse
    /// that the spline misses the curve's shape, several equal extrema (one is returned).
    /// Errors: R <= 0, m < 3, non-finite points, `cl[0] == cl[1]`, |cl - cc| != R (> 0.1 %).
    pub fn solve(
        &mut self,
        tool_radius_mm: f64,
        cl: [[f64; 3]; 2],
        cc: &[[f64; 3]],
    ) -> Result<StepError> {
        let seg = prepare(tool_radius_mm, cl, cc)?;
        if self.uniform_lanes(cc.len()) {
            let [e] = self
                .one
                .solve(&self.factors, tool_radius_mm, &[seg], self.both);
            return Ok(e);
        }
        self.solve_general(tool_radius_mm, seg)
    }

    /// Exact step errors of many segments (as [`StepErrorSolver::solve`], bit-identical), four
    /// consecutive segments with the same number of points solved side by side: the scalar
    /// algorithm is a few long chains of dependent operations, and four independent ones
    /// overlap (and, with AVX2, share registers). Units: mm in, mm out; reference and bad
    /// cases as [`StepErrorSolver::solve`]. Errors: the first bad segment's, as
    /// [`Error::InSegment`] with its position in `segments`.
    pub fn solve_batch<'a>(
        &mut self,
        tool_radius_mm: f64,
        segments: impl IntoIterator<Item = SegmentRef<'a>>,
    ) -> Result<Vec<StepError>> {
        let r = tool_radius_mm;
        let at = |index: usize| {
            move |e: Error| Error::InSegment {
                index,
                source: Box::new(e),
            }
        };
        let mut it = segments.into_iter().enumerate().peekable();
        let mut out = Vec::with_capacity(it.size_hint().0);
        while let Some((i, first)) = it.next() {
            if i % 256 < BATCH_LANES {
                crate::numeric::stop::check();
            }
            let m = first.1.len();
            let mut group = [first; BATCH_LANES];
            let mut n = 1;
            if self.uniform_lanes(m) {
                while n < BATCH_LANES {
                    match it.next_if(|(_, (_, c))| c.len() == m) {
                        Some((_, seg)) => group[n] = seg,
                        None => break,
                    }
                    n += 1;
                }
            }
            let lanes = if n == BATCH_LANES {
                self.many
                    .solve_unchecked(&self.factors, r, &group, self.both)
            } else {
                None
            };
            if let Some(e) = lanes {
                out.extend(e);
                continue;
            }
            // A short group, other knots, or an invalid segment: one at a time (the first
            // error then names its segment).
            for (g, &(cl, cc)) in group[..n].iter().enumerate() {
                out.push(self.solve(r, cl, cc).map_err(at(i + g))?);
            }
        }
        Ok(out)
    }

    /// [`StepErrorSolver::solve`] through the general (spline) path whatever the knots, to check
    /// the lane path against it.
    #[cfg(test)]
    pub(super) fn solve_via_spline(
        &mut self,
        r: f64,
        cl: [[f64; 3]; 2],
        cc: &[[f64; 3]],
    ) -> Result<StepError> {
        let seg = prepare(r, cl, cc)?;
        self.solve_general(r, seg)
    }

    /// True when segments of m points take the lane path (uniform knots, m >= 4); grows the
    /// Thomas factors it needs.
    fn uniform_lanes(&mut self, m: usize) -> bool {
        if self.param != Parameterization::Uniform || m < 4 {
            return false;
        }
        if self.factors.len() < m - 4 {
            let mut f = 0.0;
            self.factors.clear();
            self.factors.extend((0..m - 4).map(|_| {
                f = 1.0 / (4.0 - f);
                f
            }));
        }
        true
    }

    /// The solve through [`CubicSpline3`] (any parameterization, m >= 3): the same algorithm
    /// as the lane path, one segment at a time.
    /// Errors: coincident consecutive points with chord-length parameterization.
    fn solve_general(&mut self, r: f64, seg: Prepared<'_>) -> Result<StepError> {
        let Prepared { a, u, n_mid, cc } = seg;
        self.spline.fit(cc, self.param)?;
        let sp = &self.spline;
        let kappa_mid = dot(sp.eval_d2(0.5), n_mid);
        let convex = kappa_mid < 0.0;
        // The knots' squared distances to the CL line (monotone in L, so the same extremum, no
        // sqrt) and the signs of their curvature along n_mid (an inflection when one opposes
        // the middle's); then the nearest and the farthest CC point without data-dependent
        // branches (a running argmin's branches mispredict), min / max in four lanes.
        let m = cc.len();
        self.knot_dist2.resize(m, 0.0);
        let (pts, curv) = (&sp.points()[..m], &sp.knot_d2()[..m]);
        let (mut smin, mut smax) = (f64::INFINITY, f64::NEG_INFINITY);
        for ((g, p), c) in self.knot_dist2.iter_mut().zip(pts).zip(curv) {
            let q = sub(*p, a);
            let w = cross(q, u);
            *g = dot(w, w);
            let s = dot(*c, n_mid);
            smin = if s < smin { s } else { smin };
            smax = if s > smax { s } else { smax };
        }
        let (any_neg, any_pos) = (smin < 0.0, smax > 0.0);
        let kd = &self.knot_dist2[..m];
        let (dmin, dmax) = min_max(kd);
        let (mut kmin, mut kmax) = (0, 0);
        for (k, &g) in kd.iter().enumerate() {
            kmin = if g == dmin { k } else { kmin };
            kmax = if g == dmax { k } else { kmax };
        }
        let inflection = if convex { any_pos } else { any_neg };
        let line = Line { a, u };
        let branch = |minimize: bool| {
            if minimize {
                extremum(sp, &line, kd, kmin, true)
            } else {
                extremum(sp, &line, kd, kmax, false)
            }
        };
        let best = branch(convex);
        let other = (inflection || self.both).then(|| branch(!convex));
        let l = best.d2.sqrt();
        let one_sided = |l: f64, convex: bool| if convex { r - l } else { l - r };
        let other_side_mm = other.map_or(f64::NAN, |o| one_sided(o.d2.sqrt(), !convex));
        Ok(StepError {
            error_mm: (r - l).abs(),
            signed_mm: one_sided(l, convex),
            distance_mm: l,
            t: best.t,
            point: best.point,
            convex,
            inflection,
            other_side_mm,
        })
    }
}

/// Checks one segment and derives its frame. Errors: see [`StepErrorSolver::solve`].
pub(super) fn prepare(r: f64, cl: [[f64; 3]; 2], cc: &[[f64; 3]]) -> Result<Prepared<'_>> {
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
    if !all_finite(cl.as_flattened()) || !all_finite(cc.as_flattened()) {
        check_points("cl", &cl)?;
        check_points("cc", cc)?;
    }
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
    Ok(Prepared { a, u, n_mid, cc })
}

/// Fast check that every coordinate is finite, on the bits: `(bits & EXP) + EXP_LSB` carries
/// into the sign bit exactly when the exponent is all ones (inf, NaN). An OR of those, with no
/// early exit, vectorises; the slow check then names the bad point.
#[inline(always)]
pub(super) fn all_finite(v: &[f64]) -> bool {
    const EXP: u64 = 0x7FF0_0000_0000_0000;
    const EXP_LSB: u64 = 0x0010_0000_0000_0000;
    v.iter()
        .fold(0u64, |acc, x| acc | ((x.to_bits() & EXP) + EXP_LSB))
        >> 63
        == 0
}

/// (min, max) of a non-empty slice without NaN, in four independent lanes.
#[inline]
pub(super) fn min_max(v: &[f64]) -> (f64, f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 4], [f64::NEG_INFINITY; 4]);
    let mut chunks = v.chunks_exact(4);
    for c in &mut chunks {
        for i in 0..4 {
            lo[i] = if c[i] < lo[i] { c[i] } else { lo[i] };
            hi[i] = if c[i] > hi[i] { c[i] } else { hi[i] };
        }
    }
    for (i, &x) in chunks.remainder().iter().enumerate() {
        lo[i] = if x < lo[i] { x } else { lo[i] };
        hi[i] = if x > hi[i] { x } else { hi[i] };
    }
    (
        lo[0].min(lo[1]).min(lo[2].min(lo[3])),
        hi[0].max(hi[1]).max(hi[2].max(hi[3])),
    )
}

/// The CL line: a point and a unit direction.
pub(super) struct Line {
    a: [f64; 3],
    u: [f64; 3],
}

/// An extremal point of the distance: spline parameter, squared distance (mm^2), point (mm).
pub(super) struct Extremum {
    t: f64,
    d2: f64,
    point: [f64; 3],
}

/// One spline piece `Q(b) = Σ c_j b^j` and the part of `Q(b) - a` normal to the CL line,
/// `P(b) = Σ n_j b^j` (`n_j` = the `c_j` with their component along `u` removed).
pub(super) struct Piece {
    c: [[f64; 3]; 4],
    n: [[f64; 3]; 4],
}

impl Piece {
    #[inline]
    fn new(c: [[f64; 3]; 4], line: &Line) -> Self {
        let perp = |v: [f64; 3]| {
            let s = dot(v, line.u);
            [
                v[0] - s * line.u[0],
                v[1] - s * line.u[1],
                v[2] - s * line.u[2],
            ]
        };
        Piece {
            c,
            n: [perp(sub(c[0], line.a)), perp(c[1]), perp(c[2]), perp(c[3])],
        }
    }

    /// `Q(b)`, mm.
    #[inline]
    fn point(&self, b: f64) -> [f64; 3] {
        let c = &self.c;
        std::array::from_fn(|d| ((c[3][d] * b + c[2][d]) * b + c[1][d]) * b + c[0][d])
    }

    /// `L^2(b) = |P(b)|^2`, mm^2.
    #[inline]
    fn dist2(&self, b: f64) -> f64 {
        let n = &self.n;
        let p: [f64; 3] =
            std::array::from_fn(|d| ((n[3][d] * b + n[2][d]) * b + n[1][d]) * b + n[0][d]);
        dot(p, p)
    }

    /// `s g(b)` at `b = 0` and `b = 1`, with `g = P · P' = (L^2)'/2`.
    #[inline]
    fn end_slopes(&self, s: f64) -> (f64, f64) {
        let n = &self.n;
        let p1: [f64; 3] = std::array::from_fn(|d| n[0][d] + n[1][d] + n[2][d] + n[3][d]);
        let d1: [f64; 3] = std::array::from_fn(|d| n[1][d] + 2.0 * n[2][d] + 3.0 * n[3][d]);
        (s * dot(n[0], n[1]), s * dot(p1, d1))
    }

    /// `(g, g', g'')` at `b`: `g = P · P'`, `g' = |P'|^2 + P · P''`, `g'' = 3 P' · P'' + P · P'''`.
    #[inline]
    #[allow(clippy::needless_range_loop)] // one index over the four coefficient vectors
    fn slope(&self, b: f64) -> (f64, f64, f64) {
        let n = &self.n;
        let (mut g, mut g1, mut g2) = (0.0, 0.0, 0.0);
        for d in 0..3 {
            let p = ((n[3][d] * b + n[2][d]) * b + n[1][d]) * b + n[0][d];
            let p1 = (3.0 * n[3][d] * b + 2.0 * n[2][d]) * b + n[1][d];
            let p2 = 6.0 * n[3][d] * b + 2.0 * n[2][d];
            let p3 = 6.0 * n[3][d];
            g += p * p1;
            g1 += p1 * p1 + p * p2;
            g2 += 3.0 * p1 * p2 + p * p3;
        }
        (g, g1, g2)
    }
}

/// The minimum (`minimize`) or maximum of the distance to the CL line on the spline, starting
/// from knot `k`, the best of the knots (`kd`: the knots' squared distances).
pub(super) fn extremum(
    sp: &CubicSpline3,
    line: &Line,
    kd: &[f64],
    k: usize,
    minimize: bool,
) -> Extremum {
    let s = if minimize { 1.0 } else { -1.0 };
    let knots = sp.knots();
    let m = knots.len();
    let at_knot = Extremum {
        t: knots[k],
        d2: kd[k],
        point: sp.points()[k],
    };
    // s L^2 decreases away from the knot on one side (its slope there, the same on both
    // pieces as the spline is C1, says which); guess the side of the better neighbour first.
    let mut left = k + 1 == m || (k > 0 && s * kd[k - 1] < s * kd[k + 1]);
    let mut piece = Piece::new(sp.piece(if left { k - 1 } else { k }), line);
    let (mut f0, mut f1) = piece.end_slopes(s);
    let at = if left { f1 } else { f0 };
    if at == 0.0 {
        return at_knot;
    }
    if (at < 0.0) == left {
        // The other side; at an end knot, with s L^2 rising inwards, the knot is the extremum.
        if (left && k + 1 == m) || (!left && k == 0) {
            return at_knot;
        }
        left = !left;
        piece = Piece::new(sp.piece(if left { k - 1 } else { k }), line);
        (f0, f1) = piece.end_slopes(s);
    }
    let j = if left { k - 1 } else { k };
    // The stationary point is bracketed when f = s g goes from <= 0 to >= 0 over the piece
    // (the knot's end has the right sign; the far end usually does).
    let b = if f0 <= 0.0 && f1 >= 0.0 {
        halley(&piece, s, f0, f1)
    } else {
        brent::minimize(|b| s * piece.dist2(b), 0.0, 1.0, TOL_BRENT, 100).0
    };
    let d2 = piece.dist2(b);
    if s * d2 >= s * kd[k] {
        return at_knot;
    }
    Extremum {
        t: knots[j] + b * (knots[j + 1] - knots[j]),
        d2,
        point: piece.point(b),
    }
}

/// Root of `f = s g` in [0, 1] given `f(0) = f0 <= 0 <= f(1) = f1`: Halley's iteration
/// `b <- b - 2 f f' / (2 f'^2 - f f'')` from the secant root, kept inside the shrinking
/// bracket (a bisection step when it leaves it), without data-dependent branches on the
/// bracket update.
pub(super) fn halley(piece: &Piece, s: f64, f0: f64, f1: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let mut x = if f1 > f0 { f0 / (f0 - f1) } else { 0.5 };
    for _ in 0..64 {
        let (g, g1, g2) = piece.slope(x);
        let (f, df, ddf) = (s * g, s * g1, s * g2);
        let neg = f < 0.0;
        lo = if neg { x } else { lo };
        hi = if neg { hi } else { x };
        let mut next = x - 2.0 * f * df / (2.0 * df * df - f * ddf);
        let mut tol = TOL_HALLEY;
        if !(next >= lo && next <= hi) {
            next = 0.5 * (lo + hi);
            tol = TOL_B;
        }
        if (next - x).abs() <= tol || hi - lo <= TOL_B {
            return next;
        }
        x = next;
    }
    x
}

/// Exact step error of one segment with a fresh solver (uniform parameterization).
/// See [`StepErrorSolver::solve`].
pub fn step_error(tool_radius_mm: f64, segment: &StepErrorSegment) -> Result<StepError> {
    StepErrorSolver::default().solve(tool_radius_mm, segment.cl, &segment.cc)
}

/// Exact step errors of a batch of segments, split over up to `threads` threads (0 = all
/// cores), each running [`StepErrorSolver::solve_batch`] (four segments side by side).
/// Units: mm. Errors name the first bad segment's index ([`Error::InSegment`]).
pub fn step_errors(
    tool_radius_mm: f64,
    segments: &[StepErrorSegment],
    threads: usize,
) -> Result<Vec<StepError>> {
    let range = |a: usize, b: usize| segments[a..b].iter().map(|s| (s.cl, &s.cc[..]));
    step_errors_split(tool_radius_mm, segments.len(), threads, 1024, range)
}

/// [`step_errors`] of `n` segments in any storage (`range(from, to)` yields `from..to`), the
/// one thread split of the exact step error (also of `step_error::solve_batch`'s flat
/// batches): up to `threads` threads (0 = all cores), each taking at least `min_per_thread`
/// segments, the caller the first share. Units: mm. Errors: as [`step_errors`].
pub fn step_errors_split<'a, I>(
    tool_radius_mm: f64,
    n: usize,
    threads: usize,
    min_per_thread: usize,
    range: impl Fn(usize, usize) -> I + Sync,
) -> Result<Vec<StepError>>
where
    I: Iterator<Item = SegmentRef<'a>>,
{
    let per = parallel::chunk_len(n, threads, min_per_thread).max(1);
    let run = |from: usize| -> Result<Vec<StepError>> {
        let segs = range(from, (from + per).min(n));
        StepErrorSolver::default()
            .solve_batch(tool_radius_mm, segs)
            .map_err(|e| match e {
                Error::InSegment { index, source } => Error::InSegment {
                    index: from + index,
                    source,
                },
                e => e,
            })
    };
    if n <= per {
        return run(0);
    }
    // One scoped thread per share of `per` segments (numeric::parallel, the one split).
    let starts: Vec<usize> = (0..n).step_by(per).collect();
    let parts = parallel::map_chunks(&starts, 1, |_, from| run(from[0]));
    let mut out = Vec::with_capacity(n);
    for p in parts {
        out.extend(p?);
    }
    Ok(out)
}
