//! The original (reference) path as a polyline of its interpolated samples with the corner
//! points inserted, the choice of the points the compensated program is made of, and the foot
//! points of a simulated actual path on the reference.
//!
//! The samples of the original interpolation lie exactly on the programmed path (the
//! interpolator evaluates each block's geometry), so the chords between them deviate from it
//! by the sagitta `h²κ/8` only (0.03 µm for 0.05 mm spacing on R 10 mm); the corners the
//! interpolator reports ([`crate::motion::Corner`]) are knots of their own, as in
//! [`crate::motion::contour_error`].

use crate::motion::gcode::Feed;
use crate::motion::{Machine, Program, Trajectory};
use crate::numeric::vec3::{dist, dot, sub};

/// Reference polyline of the original path (workpiece frame = machine frame on `xyz`).
pub(super) struct Reference {
    /// Distinct knots, mm.
    pub knots: Vec<[f64; 3]>,
    /// Cumulative chord length at each knot, mm.
    pub cum: Vec<f64>,
    /// 1-based source line of the block whose motion ends at the knot.
    pub line: Vec<usize>,
    /// Programmed feed (mm/min) of that block (G0: the machine's rapid rate).
    pub feed_mm_min: Vec<f64>,
    /// The knot is a corner of the programmed path (or its end).
    pub corner: Vec<bool>,
    /// The original runs at its block's cruise speed at this knot.
    pub steady: Vec<bool>,
    /// Speed of the original command leaving the knot (a corner: arriving at it), mm/s.
    pub speed_mm_s: Vec<f64>,
    /// Bounding sphere (centre, radius, mm) of each run of [`BOUND_SEGMENTS`] segments
    /// (segments `b·BOUND_SEGMENTS ..`), built by [`Reference::new`]: lets [`Reference::feet`]
    /// pass over runs that cannot hold a nearer foot.
    bounds: Vec<([f64; 3], f64)>,
    /// The same for runs of [`BOUND_SEGMENTS`]² segments.
    bounds_wide: Vec<([f64; 3], f64)>,
}

/// Distances (mm) within which two segments count as equally near a tip for
/// [`Reference::feet_hinted`].
const TIE_MM: f64 = 1e-9;

/// Farthest (mm of arc) the forward scan of [`Reference::feet_hinted`] reaches beyond its
/// window towards the hint.
const HINT_REACH_MM: f64 = 20.0;

/// Segments per bounding sphere of [`Reference::feet`]'s search (and the factor between its
/// two levels).
const BOUND_SEGMENTS: usize = 16;

/// Feed (mm/min) of `block` as the interpolator plans it along the path.
fn feed_of(machine: &Machine, feed: Feed, len_mm: f64) -> f64 {
    match feed {
        Feed::Rapid => machine.rapid_mm_min,
        Feed::PerMinute(f) => f,
        Feed::InverseTime(f) => len_mm * f,
    }
}

impl Reference {
    /// Builds the reference from the original `program` and its interpolation `cmd`.
    pub fn new(machine: &Machine, program: &Program, cmd: &Trajectory) -> Reference {
        let n = cmd.t.len();
        let at = |i: usize| [cmd.axes[0][i], cmd.axes[1][i], cmd.axes[2][i]];
        // Block of each sample: walk the program's blocks along the line tags.
        let mut feed = Vec::with_capacity(n);
        let mut block_id = Vec::with_capacity(n);
        let mut p = 0usize;
        for &l in &cmd.line {
            let mut q = p;
            while q < program.blocks.len() && program.blocks[q].line != l as usize {
                q += 1;
            }
            if q < program.blocks.len() {
                p = q;
            }
            let b = &program.blocks[p.min(program.blocks.len() - 1)];
            feed.push(feed_of(machine, b.feed, b.xyz_length()));
            block_id.push(p);
        }
        // Speed per sample (forward difference).
        let speed: Vec<f64> = (0..n)
            .map(|i| {
                if i + 1 < n {
                    dist(at(i), at(i + 1)) / cmd.period_s
                } else {
                    0.0
                }
            })
            .collect();
        // Steady: at the programmed feed (to 1 ppm) from two samples before to two after, in
        // one block (where the original ramps, extra block boundaries would slow the
        // jerk-limited planner down: every block starts and ends at zero acceleration).
        let steady_sample = |i: usize| {
            let ok = |k: usize| {
                k < n && speed[k] >= (1.0 - 1e-6) * feed[k] / 60.0 && block_id[k] == block_id[i]
            };
            i >= 2 && (i - 2..=i + 2).all(ok)
        };
        let mut r = Reference {
            knots: Vec::with_capacity(n),
            cum: Vec::with_capacity(n),
            line: Vec::with_capacity(n),
            feed_mm_min: Vec::with_capacity(n),
            corner: Vec::with_capacity(n),
            steady: Vec::with_capacity(n),
            speed_mm_s: Vec::with_capacity(n),
            bounds: Vec::new(),
            bounds_wide: Vec::new(),
        };
        let mut corners = cmd.corners.iter().peekable();
        for i in 0..n {
            let prev = i.saturating_sub(1);
            while let Some(c) = corners.next_if(|c| c.before_sample <= i) {
                let tip = [c.axes[0], c.axes[1], c.axes[2]];
                r.push(tip, cmd.line[prev] as usize, feed[prev], true, false);
                r.speed_mm_s.push(speed[prev]);
                r.speed_mm_s.truncate(r.knots.len());
            }
            r.push(
                at(i),
                cmd.line[i] as usize,
                feed[i],
                i + 1 == n,
                steady_sample(i),
            );
            r.speed_mm_s.push(speed[i]);
            r.speed_mm_s.truncate(r.knots.len());
        }
        r.bounds = sphere_bounds(&r.knots, BOUND_SEGMENTS);
        r.bounds_wide = sphere_bounds(&r.knots, BOUND_SEGMENTS * BOUND_SEGMENTS);
        r
    }

    fn push(&mut self, p: [f64; 3], line: usize, feed: f64, corner: bool, steady: bool) {
        if let Some(last) = self.knots.last()
            && dist(*last, p) <= 1e-9
        {
            let k = self.corner.len() - 1;
            self.corner[k] |= corner;
            self.steady[k] &= steady;
            return;
        }
        let c = self.knots.last().map_or(0.0, |l| dist(*l, p)) + self.cum.last().unwrap_or(&0.0);
        self.knots.push(p);
        self.cum.push(c);
        self.line.push(line);
        self.feed_mm_min.push(feed);
        self.corner.push(corner);
        self.steady.push(steady);
    }

    /// Point (mm) at arc parameter `sigma` (mm, clamped to the path) and the unit direction
    /// of the chord it lies on (the path's tangent there, within half a chord's turn).
    pub fn point_at(&self, sigma: f64) -> ([f64; 3], [f64; 3]) {
        let n = self.knots.len();
        if n < 2 {
            return (self.knots.first().copied().unwrap_or([0.0; 3]), [0.0; 3]);
        }
        let i = self.cum.partition_point(|c| *c <= sigma).clamp(1, n - 1);
        let (a, b) = (self.knots[i - 1], self.knots[i]);
        let len = self.cum[i] - self.cum[i - 1];
        let f = if len > 0.0 {
            ((sigma - self.cum[i - 1]) / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let p = std::array::from_fn(|d| a[d] + f * (b[d] - a[d]));
        let t = if len > 0.0 {
            std::array::from_fn(|d| (b[d] - a[d]) / len)
        } else {
            [0.0; 3]
        };
        (p, t)
    }

    /// Largest speed (mm/s) of the original command over the arc parameters `lo..=hi` (mm).
    pub fn max_speed(&self, lo: f64, hi: f64) -> f64 {
        let a = self.cum.partition_point(|c| *c < lo).saturating_sub(1);
        let b = self.cum.partition_point(|c| *c <= hi).min(self.cum.len());
        self.speed_mm_s[a..b].iter().fold(0.0, |m, v| m.max(*v))
    }

    /// Largest distance (mm) of the knots strictly between `a` and `b` from the chord
    /// `knots[a]→knots[b]`, estimated on the middle and quarter knots (exact for arcs).
    fn chord_deviation(&self, a: usize, b: usize) -> f64 {
        if b <= a + 1 {
            return 0.0;
        }
        [(a + b) / 2, (3 * a + b) / 4, (a + 3 * b) / 4]
            .iter()
            .filter(|&&k| k > a && k < b)
            .map(|&k| chord_distance(&self.knots[a], &self.knots[b], &self.knots[k]).0)
            .fold(0.0, f64::max)
    }

    /// Indices of the knots that become points of the compensated program (the first is knot
    /// 0, the start, which is not emitted): every corner and the end; where the original
    /// cruises, one knot every `every` knots; elsewhere (speed ramps, where short blocks would
    /// slow the jerk-limited planner down) as few as keep every chord within `chord_tol_mm` of
    /// the path.
    pub fn choose_points(&self, every: usize, chord_tol_mm: f64) -> Vec<usize> {
        let k = self.knots.len();
        let mut out = vec![0usize];
        let mut last = 0usize;
        for i in 1..k {
            let must = self.corner[i] || i + 1 == k;
            let next_bad = i + 1 < k && self.chord_deviation(last, i + 1) > chord_tol_mm;
            let due = self.steady[i] && i - last >= every;
            if must || next_bad || due {
                out.push(i);
                last = i;
            }
        }
        out
    }

    /// Foot point of every `actual` tool tip on the reference: `(s, e)` with `s` the arc
    /// parameter of the foot (mm) and `e = actual − foot` (mm). The search starts from the
    /// previous sample's foot (the foot moves continuously) and spans `8·d` of arc on either
    /// side, `d` the distance to that start: any nearer path point lies within `2d` of it in
    /// space, and within `8d` along a path with inner angles above 29° (the window of
    /// [`crate::motion::contour_error`]).
    pub fn feet(&self, actual: &[[f64; 3]]) -> Vec<(f64, [f64; 3])> {
        self.feet_hinted(actual, None)
    }

    /// [`Reference::feet`] with, per tip, the arc parameter `hint` (mm) the command is heading
    /// for: between segments equally near (within [`TIE_MM`]) the foot takes the one nearer
    /// the hint in arc. Where the path retraces itself (up to a clearance plane and back down
    /// the same line to the plunge) both passes are equally near, and without the hint the
    /// foot would slide back down the pass the tool has left.
    pub fn feet_hinted(&self, actual: &[[f64; 3]], hint: Option<&[f64]>) -> Vec<(f64, [f64; 3])> {
        let nseg = self.knots.len().saturating_sub(1);
        let mut out = Vec::with_capacity(actual.len());
        if nseg == 0 {
            for a in actual {
                let k = self.knots[0];
                out.push((0.0, [a[0] - k[0], a[1] - k[1], a[2] - k[2]]));
            }
            return out;
        }
        let mut prev = 0usize;
        let b = BOUND_SEGMENTS;
        // A run of segments is passed over when its bounding sphere lies farther from the tip
        // than the best distance found (with a margin for rounding): none of its segments
        // could then be strictly nearer, so the foot is the one the plain scan finds.
        let beyond = |a: &[f64; 3], run: usize, best: f64, wide: bool| {
            let (c, r) = if wide {
                self.bounds_wide[run]
            } else {
                self.bounds[run]
            };
            let lower = dist(c, *a) - r;
            lower > best + TIE_MM + 1e-12 * (lower.abs() + r + 1.0)
        };
        let arc = |j: usize, f: f64| self.cum[j] + f * (self.cum[j + 1] - self.cum[j]);
        for (i, a) in actual.iter().enumerate() {
            let h = hint.and_then(|h| h.get(i).copied());
            // Nearer, or (with a hint) as near and nearer the hint along the path.
            let better = |d: f64, j: usize, f: f64, best: &(f64, usize, f64)| match h {
                None => d < best.0,
                Some(h) => {
                    d < best.0 - TIE_MM
                        || (d < best.0 + TIE_MM
                            && (arc(j, f) - h).abs() < (arc(best.1, best.2) - h).abs())
                }
            };
            let (d0, f0) = chord_distance(&self.knots[prev], &self.knots[prev + 1], a);
            let s0 = self.cum[prev] + f0 * (self.cum[prev + 1] - self.cum[prev]);
            let reach = 8.0 * d0 + 1e-9;
            let mut best = (d0, prev, f0);
            // Backwards: segment j - 1 is looked at while cum[j] >= s0 - reach.
            let mut j = prev;
            while j > 0 && self.cum[j] >= s0 - reach {
                let mut passed = false;
                for (len, wide) in [(b * b, true), (b, false)] {
                    if j % len == 0
                        && j >= len
                        && self.cum[j - len + 1] >= s0 - reach
                        && beyond(a, j / len - 1, best.0, wide)
                    {
                        j -= len;
                        passed = true;
                        break;
                    }
                }
                if passed {
                    continue;
                }
                j -= 1;
                let (d, f) = chord_distance(&self.knots[j], &self.knots[j + 1], a);
                if better(d, j, f, &best) {
                    best = (d, j, f);
                }
            }
            // Forwards: segment j is looked at while cum[j] <= s0 + reach.
            let mut j = prev + 1;
            // With a hint ahead and the tool moving back along the segment of its last foot
            // (as where it turns back on a retraced path), the forward scan reaches on
            // towards the hint (up to HINT_REACH_MM), where the pass ahead, as near as the
            // one behind, lies.
            let moving_back = i > 0 && {
                let t = sub(self.knots[prev + 1], self.knots[prev]);
                dot(sub(*a, actual[i - 1]), t) < 0.0
            };
            let ahead = match h {
                Some(h) if moving_back && h > s0 + reach => {
                    reach.max((h - s0).min(reach + HINT_REACH_MM))
                }
                _ => reach,
            };
            while j < nseg && self.cum[j] <= s0 + ahead {
                let mut passed = false;
                for (len, wide) in [(b * b, true), (b, false)] {
                    if j % len == 0
                        && j + len <= nseg
                        && self.cum[j + len - 1] <= s0 + ahead
                        && beyond(a, j / len, best.0, wide)
                    {
                        j += len;
                        passed = true;
                        break;
                    }
                }
                if passed {
                    continue;
                }
                let (d, f) = chord_distance(&self.knots[j], &self.knots[j + 1], a);
                if better(d, j, f, &best) {
                    best = (d, j, f);
                }
                j += 1;
            }
            let (_, j, f) = best;
            prev = j;
            let (p0, p1) = (self.knots[j], self.knots[j + 1]);
            let foot = [
                p0[0] + f * (p1[0] - p0[0]),
                p0[1] + f * (p1[1] - p0[1]),
                p0[2] + f * (p1[2] - p0[2]),
            ];
            let s = self.cum[j] + f * (self.cum[j + 1] - self.cum[j]);
            out.push((s, [a[0] - foot[0], a[1] - foot[1], a[2] - foot[2]]));
        }
        out
    }
}

/// Bounding spheres (centre = middle of the bounding box, radius to its farthest knot, mm,
/// rounded up) of the runs of `len` segments of the polyline `knots`.
fn sphere_bounds(knots: &[[f64; 3]], len: usize) -> Vec<([f64; 3], f64)> {
    let nseg = knots.len().saturating_sub(1);
    (0..nseg.div_ceil(len))
        .map(|run| {
            let from = run * len;
            let to = (from + len).min(nseg);
            let pts = &knots[from..=to];
            let mut lo = pts[0];
            let mut hi = pts[0];
            for p in pts {
                for d in 0..3 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
            }
            let c = std::array::from_fn(|d| 0.5 * (lo[d] + hi[d]));
            let r = pts.iter().map(|p| dist(c, *p)).fold(0.0, f64::max);
            (c, r * (1.0 + 1e-12) + 1e-12)
        })
        .collect()
}

/// Distance from `a` to the chord `p0→p1` and the fraction along it.
pub(super) fn chord_distance(p0: &[f64; 3], p1: &[f64; 3], a: &[f64; 3]) -> (f64, f64) {
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

/// Spreads the errors `feet` (arc parameter, vector) onto the points at arc parameters
/// `sigma` (ascending) with linear hat weights and returns each point's mean error (mm);
/// a point no sample fell near takes the linear interpolation of its weighted neighbours.
pub(super) fn correction(sigma: &[f64], feet: &[(f64, [f64; 3])]) -> Vec<[f64; 3]> {
    let m = sigma.len();
    let mut sum = vec![[0.0f64; 3]; m];
    let mut w = vec![0.0f64; m];
    for (s, e) in feet {
        let j = sigma.partition_point(|x| x <= s);
        let (lo, hi, f) = if j == 0 {
            (0, 0, 0.0)
        } else if j >= m {
            (m - 1, m - 1, 0.0)
        } else {
            let h = sigma[j] - sigma[j - 1];
            (j - 1, j, if h > 0.0 { (s - sigma[j - 1]) / h } else { 0.0 })
        };
        for (k, wk) in [(lo, 1.0 - f), (hi, f)] {
            if wk > 0.0 {
                w[k] += wk;
                for d in 0..3 {
                    sum[k][d] += wk * e[d];
                }
            }
        }
    }
    let have: Vec<usize> = (0..m).filter(|&k| w[k] > 1e-12).collect();
    let mut out = vec![[0.0f64; 3]; m];
    for &k in &have {
        out[k] = sum[k].map(|v| v / w[k]);
    }
    for k in 0..m {
        if w[k] > 1e-12 {
            continue;
        }
        let after = have.partition_point(|&h| h < k);
        out[k] = match (after.checked_sub(1).map(|i| have[i]), have.get(after)) {
            (Some(a), Some(&b)) => {
                let f = (sigma[k] - sigma[a]) / (sigma[b] - sigma[a]).max(1e-300);
                std::array::from_fn(|d| out[a][d] + f * (out[b][d] - out[a][d]))
            }
            (Some(a), None) => out[a],
            (None, Some(&b)) => out[b],
            (None, None) => [0.0; 3],
        };
    }
    out
}

/// Smooths the per-point corrections `c` along the arc parameter `sigma` (ascending, mm) with
/// a triangular kernel of half-width `half_mm[k]` around point `k` (mm), never across a point
/// where `brk` is true (a corner, which keeps its own correction and bounds the window): the
/// servo cannot reproduce features of the correction shorter than a few periods of travel,
/// and kinks between neighbouring points would only slow the interpolator down.
pub(super) fn smooth(
    c: &[[f64; 3]],
    sigma: &[f64],
    half_mm: &[f64],
    brk: &[bool],
) -> Vec<[f64; 3]> {
    let m = c.len();
    (0..m)
        .map(|k| {
            if brk[k] {
                return c[k];
            }
            let h = half_mm[k].max(1e-12);
            let mut acc = [0.0f64; 3];
            let mut wsum = 0.0;
            let mut add = |j: usize| {
                let w = 1.0 - (sigma[j] - sigma[k]).abs() / h;
                if w > 0.0 {
                    wsum += w;
                    for d in 0..3 {
                        acc[d] += w * c[j][d];
                    }
                }
            };
            add(k);
            let mut j = k;
            while j > 0 && !brk[j - 1] && sigma[k] - sigma[j - 1] < h {
                j -= 1;
                add(j);
            }
            let mut j = k + 1;
            while j < m && !brk[j] && sigma[j] - sigma[k] < h {
                add(j);
                j += 1;
            }
            acc.map(|v| v / wsum)
        })
        .collect()
}
