//! Contour error: distance from the simulated tool tip to the commanded path.
//!
//! Zhang & Chen 2025 §4.2: the commanded samples are joined into a continuous path by cubic-spline
//! interpolation (here a natural cubic spline through the distinct commanded tool-tip
//! points, chord-length parameterized), and each actual point is matched to the nearest
//! point of that path inside a window around its own command sample whose size follows
//! the tracking error (eq. 11 takes the minimum distance inside the window). The foot point
//! is within `|e|` of the actual point, hence within `2|e|` of the command sample in space;
//! on a smooth path that is within about `2|e|` of arc, but across a corner the arc is
//! longer (√2 times at 90°), so the window is every segment within arc length `8|e|` of the
//! command sample, and further while segments still come within `2|e|` in space. Passes of
//! the path that come close again later are deliberately not matched.
//!
//! Corners: the programmed path turns at block junctions that the samples straddle (the
//! junction speed is not zero), so the interpolator reports each corner point
//! ([`super::interpolate::Corner`]); it becomes a knot at which the spline restarts (natural
//! ends), so the path keeps its corner instead of a spline or chord rounding it off. With
//! both, the contour error at corners equals the distance to the programmed path to 0.1 µm
//! (`contour_error_at_corners_is_the_distance_to_the_programmed_path`).
//!
//! Hand-written spline (no crate): a tridiagonal solve and a per-segment Newton projection.

use super::interpolate::Corner;
use super::kinematics::{Kinematics, angle_between_deg};
use crate::numeric::tridiag::Tridiagonal;
use crate::numeric::vec3::{dist, dot};

/// Contour and tracking errors of a simulated run.
#[derive(Clone, Debug, PartialEq)]
pub struct ContourReport {
    /// Distance (mm) from the actual tool tip at each sample to the commanded path.
    pub contour_error: Vec<f64>,
    /// max of `contour_error`, mm.
    pub max: f64,
    /// RMS of `contour_error`, mm.
    pub rms: f64,
    /// Per axis max |commanded − actual| (mm or deg), axis order X, Y, Z[, A, C].
    pub tracking_max: Vec<f64>,
    /// Per axis RMS of commanded − actual (mm or deg).
    pub tracking_rms: Vec<f64>,
    /// 5-axis only: angle (deg) between the actual tool axis and the commanded tool axis at
    /// the foot point of the contour error.
    pub orientation_error_deg: Option<Vec<f64>>,
    /// max of `orientation_error_deg`.
    pub orientation_max_deg: Option<f64>,
}

/// Natural cubic spline through points, chord-length parameterized.
struct PathSpline {
    pts: Vec<[f64; 3]>,
    /// Second derivatives at the knots (d²P/dt², t = chord length).
    m2: Vec<[f64; 3]>,
    /// Segment chord lengths.
    h: Vec<f64>,
}

impl PathSpline {
    /// The spline through `pts`, natural (zero second derivative) at both ends and at every
    /// knot where `breaks` is true: the path's corners, where the programmed path turns and
    /// a spline through it would round the corner off.
    fn new(pts: Vec<[f64; 3]>, breaks: &[bool]) -> Self {
        let n = pts.len();
        let h: Vec<f64> = pts.windows(2).map(|w| dist(w[0], w[1])).collect();
        let mut m2 = vec![[0.0; 3]; n];
        let mut start = 0;
        for end in 1..n {
            if end < n - 1 && !breaks[end] {
                continue;
            }
            // One piece: knots start..=end, interior start+1..end (natural at both ends).
            if end - start >= 2 {
                let mut tri = Tridiagonal::new();
                for i in start + 1..end {
                    tri.push_row(h[i - 1], 2.0 * (h[i - 1] + h[i]), h[i]);
                    for d in 0..3 {
                        m2[i][d] = 6.0
                            * ((pts[i + 1][d] - pts[i][d]) / h[i]
                                - (pts[i][d] - pts[i - 1][d]) / h[i - 1]);
                    }
                }
                tri.solve_in_place(&mut m2[start + 1..end]);
            }
            start = end;
        }
        PathSpline { pts, m2, h }
    }

    /// Point, first and second derivative of segment `j` at local `tau ∈ [0, h_j]`.
    fn eval(&self, j: usize, tau: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let h = self.h[j];
        let (p0, p1) = (&self.pts[j], &self.pts[j + 1]);
        let (m0, m1) = (&self.m2[j], &self.m2[j + 1]);
        let mut p = [0.0; 3];
        let mut d1 = [0.0; 3];
        let mut d2 = [0.0; 3];
        for d in 0..3 {
            let b = (p1[d] - p0[d]) / h - h * (2.0 * m0[d] + m1[d]) / 6.0;
            let c = m0[d] / 2.0;
            let e = (m1[d] - m0[d]) / (6.0 * h);
            p[d] = p0[d] + tau * (b + tau * (c + tau * e));
            d1[d] = b + tau * (2.0 * c + 3.0 * e * tau);
            d2[d] = 2.0 * c + 6.0 * e * tau;
        }
        (p, d1, d2)
    }

    /// Nearest point of segment `j` to `a`: (distance, local parameter fraction 0..1).
    fn project(&self, j: usize, a: &[f64; 3], frac0: f64) -> (f64, f64) {
        let h = self.h[j];
        let mut tau = frac0 * h;
        for _ in 0..8 {
            let (p, d1, d2) = self.eval(j, tau);
            let r = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
            let g1 = dot(r, d1);
            let g2 = dot(d1, d1) + dot(r, d2);
            if g2 <= 0.0 {
                break;
            }
            let next = (tau - g1 / g2).clamp(0.0, h);
            let done = (next - tau).abs() <= 1e-12 * h;
            tau = next;
            if done {
                break;
            }
        }
        let (p, _, _) = self.eval(j, tau);
        (dist(p, *a), tau / h)
    }
}

/// Distance from `a` to the chord `p0→p1` and the fraction along it.
fn chord_distance(p0: &[f64; 3], p1: &[f64; 3], a: &[f64; 3]) -> (f64, f64) {
    let d = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
    let r = [a[0] - p0[0], a[1] - p0[1], a[2] - p0[2]];
    let dd = dot(d, d);
    let f = if dd > 0.0 {
        (dot(r, d) / dd).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = [p0[0] + f * d[0], p0[1] + f * d[1], p0[2] + f * d[2]];
    (dist(q, *a), f)
}

/// First knot index `k ≤ j` with `cum[k] ≥ target` (`cum` ascending, `cum[j] > target`),
/// by exponential search backward from `j`: skips are short, the array is not.
fn gallop_back(cum: &[f64], j: usize, target: f64) -> usize {
    let mut step = 1;
    let mut hi = j;
    loop {
        let lo = hi.saturating_sub(step);
        if lo == 0 || cum[lo] < target {
            return lo + cum[lo..hi].partition_point(|&c| c < target);
        }
        hi = lo;
        step *= 2;
    }
}

/// Last knot index `k ≥ j` with `cum[k] ≤ target` (`cum[j] ≤ target`), exponential search.
fn gallop_forward(cum: &[f64], j: usize, target: f64) -> usize {
    let mut step = 1;
    let mut lo = j;
    loop {
        let hi = (lo + step).min(cum.len() - 1);
        if hi == cum.len() - 1 || cum[hi] > target {
            return lo + cum[lo..=hi].partition_point(|&c| c <= target) - 1;
        }
        lo = hi;
        step *= 2;
    }
}

/// Arc-length reach of the search window in units of its spatial radius (see the module doc).
const CORNER_REACH: f64 = 4.0;

/// Most segments searched on either side of a command sample (guards pathological inputs).
const MAX_WINDOW: usize = 200_000;

/// Computes the contour error of `actual` against `commanded` (columns per machine axis,
/// equal lengths ≥ 1, axis order X, Y, Z[, A, C]) on a machine with kinematics `kin`.
/// Tool tips and axes come from the forward kinematics (workpiece frame).
/// Reference: Zhang & Chen 2025 §4.2, eq. 11 (see module docs for the window).
/// Bad cases: where the path passes over itself within the window (a hairpin narrower than
/// twice the tracking error) the nearer pass is matched.
pub fn contour_error(
    kin: &Kinematics,
    commanded: &[Vec<f64>],
    actual: &[Vec<f64>],
    corners: &[Corner],
) -> ContourReport {
    let n_axes = commanded.len();
    let n = commanded.first().map_or(0, Vec::len);
    let row = |cols: &[Vec<f64>], i: usize| -> [f64; 5] {
        let mut q = [0.0; 5];
        for (k, c) in cols.iter().enumerate().take(5) {
            q[k] = c[i];
        }
        q
    };
    let cmd_pose: Vec<_> = (0..n).map(|i| kin.forward(&row(commanded, i))).collect();
    let act_pose: Vec<_> = (0..n).map(|i| kin.forward(&row(actual, i))).collect();
    // Distinct knots and, per knot, its first and last sample.
    let mut knots: Vec<[f64; 3]> = Vec::new();
    let mut first: Vec<usize> = Vec::new();
    let mut last: Vec<usize> = Vec::new();
    let mut knot_of = Vec::with_capacity(n);
    let mut breaks: Vec<bool> = Vec::new();
    let mut next_corner = corners.iter().peekable();
    for (i, p) in cmd_pose.iter().enumerate() {
        if i % 4096 == 0 {
            crate::numeric::stop::check();
        }
        // The path's corners (programmed junction points) go in as knots of their own, at
        // which the spline restarts.
        while let Some(c) = next_corner.next_if(|c| c.before_sample <= i) {
            let mut q = [0.0; 5];
            for (k, v) in c.axes.iter().enumerate().take(5) {
                q[k] = *v;
            }
            let tip = kin.forward(&q).tip;
            match knots.last() {
                Some(k) if dist(*k, tip) <= 1e-9 => {
                    *breaks.last_mut().unwrap() = true;
                }
                _ => {
                    knots.push(tip);
                    first.push(i);
                    last.push(i);
                    breaks.push(true);
                }
            }
        }
        match knots.last() {
            Some(k) if dist(*k, p.tip) <= 1e-9 => {
                *last.last_mut().unwrap() = i;
            }
            _ => {
                knots.push(p.tip);
                first.push(i);
                last.push(i);
                breaks.push(false);
            }
        }
        knot_of.push(knots.len() - 1);
    }
    let spline = PathSpline::new(knots, &breaks);
    let nseg = spline.h.len();
    let mut cum = Vec::with_capacity(nseg + 1);
    cum.push(0.0);
    for h in &spline.h {
        cum.push(cum.last().copied().unwrap_or(0.0) + h);
    }
    let five = n_axes == 5;
    let mut ce = Vec::with_capacity(n);
    let mut orient = if five {
        Some(Vec::with_capacity(n))
    } else {
        None
    };
    let mut prev_seg = 0usize;
    for i in 0..n {
        let a = &act_pose[i].tip;
        let kc = knot_of[i];
        if nseg == 0 {
            ce.push(dist(spline.pts[0], *a));
            if let Some(o) = orient.as_mut() {
                o.push(angle_between_deg(&cmd_pose[i].axis, &act_pose[i].axis));
            }
            continue;
        }
        let radius = 2.0 * dist(cmd_pose[i].tip, *a) + 1e-9;
        let mut best = (f64::INFINITY, kc.min(nseg - 1), 0.0f64);
        let consider = |j: usize, best: &mut (f64, usize, f64)| {
            let (d, f) = chord_distance(&spline.pts[j], &spline.pts[j + 1], a);
            if d < best.0 {
                *best = (d, j, f);
            }
        };
        // Warm start from the previous sample's foot (the foot moves continuously), when it
        // lies inside this sample's window; it only tightens the bound used for skipping.
        if (cum[prev_seg] - cum[kc]).abs() <= radius
            || (cum[prev_seg + 1] - cum[kc]).abs() <= radius
        {
            consider(prev_seg, &mut best);
        }
        // Walk the chords backward then forward from the command knot, within arc length
        // `radius`. Lower bound: a path point at arc distance ℓ from knot P has distance
        // ≥ |a − P| − ℓ, so arc lengths shorter than |a − P| − best are skipped unexamined.
        // Across a corner the foot (always within `radius` of the command knot in space) can
        // be farther along the path than in space: √2 times at a 90° turn, 1/sin(θ/2) at an
        // inner angle θ. The window therefore spans CORNER_REACH·radius of arc (inner angles
        // down to 29°), and runs on while a segment still comes within `radius` in space.
        let pc = spline.pts[kc];
        let near = |j: usize| chord_distance(&spline.pts[j], &spline.pts[j + 1], &pc).0 <= radius;
        let lo_arc = cum[kc] - CORNER_REACH * radius;
        let mut j = kc;
        let mut steps = 0;
        while j > 0 && (cum[j] >= lo_arc || near(j - 1)) && steps < MAX_WINDOW {
            steps += 1;
            let slack = dist(spline.pts[j], *a) - best.0;
            if slack > spline.h[j - 1] {
                let target = cum[j] - slack;
                j = gallop_back(&cum, j, target);
                continue;
            }
            consider(j - 1, &mut best);
            j -= 1;
        }
        let hi_arc = cum[kc] + CORNER_REACH * radius;
        let mut j = kc;
        steps = 0;
        while j < nseg && (cum[j] <= hi_arc || near(j)) && steps < MAX_WINDOW {
            steps += 1;
            let slack = dist(spline.pts[j], *a) - best.0;
            if slack > spline.h[j] {
                let target = cum[j] + slack;
                j = gallop_forward(&cum, j, target);
                continue;
            }
            consider(j, &mut best);
            j += 1;
        }
        // Refine on the spline around the best chord (neighbours only when the chord foot
        // is at an end, where the curve may bulge towards `a` on the adjacent segment).
        let (_, jb, fb) = best;
        prev_seg = jb;
        let mut out = (f64::INFINITY, jb, fb);
        let (lo, hi) = (
            if fb <= 1e-6 { jb.saturating_sub(1) } else { jb },
            if fb >= 1.0 - 1e-6 {
                (jb + 1).min(nseg - 1)
            } else {
                jb
            },
        );
        for j in lo..=hi {
            let f0 = if j == jb {
                fb
            } else if j < jb {
                1.0
            } else {
                0.0
            };
            let (d, f) = spline.project(j, a, f0);
            if d < out.0 {
                out = (d, j, f);
            }
        }
        ce.push(out.0);
        if let Some(o) = orient.as_mut() {
            let (_, j, f) = out;
            let cmd_axis = if f <= 1e-9 {
                cmd_pose[i.clamp(first[j], last[j])].axis
            } else if f >= 1.0 - 1e-9 {
                cmd_pose[i.clamp(first[j + 1], last[j + 1])].axis
            } else {
                let (u, w) = (cmd_pose[last[j]].axis, cmd_pose[first[j + 1]].axis);
                [
                    u[0] + f * (w[0] - u[0]),
                    u[1] + f * (w[1] - u[1]),
                    u[2] + f * (w[2] - u[2]),
                ]
            };
            o.push(angle_between_deg(&cmd_axis, &act_pose[i].axis));
        }
    }
    let max = ce.iter().fold(0.0f64, |m, v| m.max(*v));
    let rms = if n > 0 {
        (ce.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt()
    } else {
        0.0
    };
    let mut tracking_max = vec![0.0; n_axes];
    let mut tracking_rms = vec![0.0; n_axes];
    for k in 0..n_axes {
        let mut ss = 0.0;
        for i in 0..n {
            let e = commanded[k][i] - actual[k][i];
            tracking_max[k] = f64::max(tracking_max[k], e.abs());
            ss += e * e;
        }
        tracking_rms[k] = if n > 0 { (ss / n as f64).sqrt() } else { 0.0 };
    }
    let orientation_max_deg = orient
        .as_ref()
        .map(|o| o.iter().fold(0.0f64, |m, v| m.max(*v)));
    ContourReport {
        contour_error: ce,
        max,
        rms,
        tracking_max,
        tracking_rms,
        orientation_error_deg: orient,
        orientation_max_deg,
    }
}

#[cfg(test)]
mod tests;
