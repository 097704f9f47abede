//! Smooth loops at outside corners (issue 24 item 4, "small overshoot loops at outside
//! corners"): an alternative to the corner stage's three split points.
//!
//! Each corner the junction limit slows is replaced, from `a` mm of path before it to `b` mm
//! after it, by G01 points on a cubic Bézier curve (equal steps of its parameter, as many as
//! make the chords [`LOOP_STEP_MM`] long on average) from the path point `s` (tangent `t_s`)
//! to the path point `e` (tangent `t_e`), with control points `C1 = s + (a + o1)·t_s − w1·d_out`
//! and `C2 = e − (b + o2)·t_e + w2·d_in` (`d_in`/`d_out` the unit tangents into and out of the
//! corner). On straight legs these are `c + o1·d_in − w1·d_out` and `c + w2·d_in − o2·d_out`,
//! `c` the corner; on an arc the loop leaves and rejoins the path along its tangent. The
//! command is carried on past the corner along the incoming direction and swings back onto
//! the outgoing leg ahead of it, so the lagging tool turns at the corner. A smooth loop of
//! short chords is run at the speed its curvature allows (the interpolator's junction rule
//! over the path of one period, `√(max_accel·R)`), well above the few mm/s at which the
//! junction limit lets a sharp 90° turn pass, so the time the braking lag costs at the corner
//! comes back. Between the tight bends, chords that need no slowing are planned by the
//! interpolator as one S-curve (its look-ahead carries the acceleration across them), so the
//! tool speeds up again on the legs between two loops.
//!
//! The six numbers per corner are found on the exact interpolation and simulation (the same
//! [`Run::evaluate`] as the other stages), in four stages, and a fifth moves the points:
//! 1. one set shared by all corners, in units of the servo's lag length `λ = v/kv` (the feed
//!    over the slowest position-loop gain): 15 starting shapes, then a pattern search;
//! 2. each corner's own, coordinate by coordinate (module `descent`);
//! 3. Levenberg–Marquardt steps on each corner's six numbers together (module `descent`);
//!
//!    stages 2 and 3 run from the best shared shape and from the [`DESCENTS`]` − 1` next best
//!    starting shapes, each twice (the room between two corners shared by their loops, and
//!    halved), and the best end is kept;
//! 4. the points between the loops are corrected for the loops' timing by the main
//!    iteration's step (module `settle`);
//! 5. every point near a corner, the loops' own among them, moves sideways by
//!    Levenberg–Marquardt (norm-optimal ILC) steps on a smooth basis of offsets (module
//!    `lateral`).
//!
//! Where the answer takes the program to its duration budget, stage 5 has no time left to
//! spend: its steps bend the loops, and a tighter bend runs slower. The search then runs a
//! second time with stages 1–4 held to [`SECOND_SHARE`] of the budget, stage 5 given all of
//! it, and the better of the two answers is kept (module `choose`). On the 2 mm staircase at
//! F 3000, kv 45, the first ended at 0.365× distance-weighted RMS, the second at 0.188×
//! (`cargo bench --bench corner_grid`, session 17, before the interpolator carried the
//! acceleration across short blocks). Where the better answer misses the RMS goal (0.3×)
//! but meets the max goal (0.5×), both run again with the max weighed [`LOW_MAX_WEIGHT`]
//! instead of [`MAX_WEIGHT`] (the staircase at F 3000, kv 30, in session 18: 0.321× →
//! 0.273× RMS, max 0.308× → 0.345×).
//!
//! The objective is the distance-weighted RMS plus 0.3× the max, each against the original's,
//! plus a steep penalty on time beyond the duration budget
//! ([`super::PredistortOptions::max_duration_ratio`]). The work of stages 1–3 is bounded by
//! [`LOOP_WORK_PERIODS`] simulated periods; stage 4 takes at most 8 simulations more. A loop stays within the smooth stretch of path
//! on either side of its corner (no turn above [`SMOOTH_TURN_DEG`] between two chords, no
//! kept line) and within 0.9 of the way to the next slowed corner, shared with that corner's
//! loop.
//!
//! Only outside corners loop (the free side of the path); a program with an inside corner
//! (G41/G42 material outside the turn) keeps the three-point stage's answer.

use super::corners::CornerSpot;
use super::measure::{distance_weighted_rms, tips_of};
use super::notes::LoopLimit;
use super::reference::Reference;
use super::run::{Eval, Run, norm, round_to, sub};
use super::{Error, POSITION_DECIMALS};

/// Mean spacing (mm) of the G01 points along a loop (20 µm; the points are at equal steps of
/// the curve's parameter): the chords stay within a fraction of a micrometre of the curve,
/// and at the loops' speeds (tens of mm/s) each chord lasts about a period, so the
/// interpolator's junction rule sees the curve's own curvature.
pub const LOOP_STEP_MM: f64 = 0.02;

/// Work bound of stages 1–3 of one loop search: simulated interpolation periods (all
/// candidates' whole programs together), 4,000,000 (some 4,000 simulations of a 1 s program).
pub const LOOP_WORK_PERIODS: usize = 4_000_000;

/// Weight of the max ratio in the search's objective (the distance-weighted RMS ratio has 1).
const MAX_WEIGHT: f64 = 0.3;

/// Weight of the max ratio in the searches run again where the answer misses the RMS goal
/// but meets the max goal (module `choose`): max traded for RMS.
const LOW_MAX_WEIGHT: f64 = 0.1;

/// Largest turn between two chords (degrees) within the stretch a loop may replace.
const SMOOTH_TURN_DEG: f64 = 10.0;

/// Descents (stages 2 and 3) from different starting shapes.
const DESCENTS: usize = 3;

/// Penalty per unit of duration ratio beyond the budget.
const LATE_WEIGHT: f64 = 100.0;

/// Share of the duration budget (`max_duration_ratio − 1`) stages 1–4 may spend in the
/// second search, run where the first took the program to its budget: the rest is left to
/// stage 5.
const SECOND_SHARE: f64 = 0.5;

/// What the loop search found: the points, the [`Run`] arrays that follow them, their
/// simulation.
pub(super) struct Loops {
    pub arrays: Arrays,
    pub eval: Eval,
    /// Simulations run.
    pub simulations: usize,
    /// The work bound [`LOOP_WORK_PERIODS`] stopped the search before it ended.
    pub bounded: bool,
    /// The answer is the second search's (stages 1–4 within [`SECOND_SHARE`] of the
    /// duration budget, run because the first took the program to it).
    pub second: bool,
}

impl Loops {
    /// The answer takes more than 95 % of the duration budget: time held the loops back.
    fn binds_time(&self, run: &Run) -> bool {
        self.eval.periods as f64 > (1.0 + 0.95 * run.time_budget) * run.orig_periods as f64
    }

    /// What held the loops back, for the notes: the duration budget where the answer takes
    /// more than 95 % of it or is the second search's (`max_duration_ratio` the run's), else
    /// the work bound where it stopped the search, else the room between the corners.
    pub(super) fn limit(&self, run: &Run, max_duration_ratio: f64) -> LoopLimit {
        let orig = run.orig_periods as f64;
        if self.binds_time(run) || self.second {
            LoopLimit::Time(max_duration_ratio)
        } else if self.bounded {
            LoopLimit::Work(orig * run.period_s)
        } else {
            LoopLimit::Room
        }
    }
}

/// Per-point arrays of a candidate (the [`Run`] fields that follow the points).
pub(super) struct Arrays {
    pub pts: Vec<[f64; 3]>,
    base_feed: Vec<f64>,
    sigma: Vec<f64>,
    base_len: Vec<f64>,
    pub lines: Vec<usize>,
    /// The point is one of a loop's.
    in_loop: Vec<bool>,
}

/// The loop of one corner for parameters `p` = `[a, b, o1, o2, w1, w2]` (mm), from the point
/// `s` (unit tangent `t_s`) `a` mm of path before the corner to the point `e` (tangent `t_e`)
/// `b` mm after it, `d_in`/`d_out` the tangents into and out of the corner: points from the
/// curve's start (excluded: it is the last point kept before the loop) to its end. On
/// straight legs the control points are `c + o1·d_in − w1·d_out` and `c + w2·d_in − o2·d_out`
/// (module docs); on an arc the loop leaves and rejoins the path along its tangents there.
fn loop_points(
    (s, t_s): ([f64; 3], [f64; 3]),
    (e, t_e): ([f64; 3], [f64; 3]),
    d_in: [f64; 3],
    d_out: [f64; 3],
    p: &[f64; 6],
) -> Vec<[f64; 3]> {
    let [a, b, o1, o2, w1, w2] = *p;
    let c1: [f64; 3] = std::array::from_fn(|d| s[d] + (a + o1) * t_s[d] - w1 * d_out[d]);
    let c2: [f64; 3] = std::array::from_fn(|d| e[d] - (b + o2) * t_e[d] + w2 * d_in[d]);
    let at = |t: f64| -> [f64; 3] {
        let u = 1.0 - t;
        std::array::from_fn(|d| {
            u * u * u * s[d] + 3.0 * u * u * t * c1[d] + 3.0 * u * t * t * c2[d] + t * t * t * e[d]
        })
    };
    let mut len = 0.0;
    let mut prev = s;
    for i in 1..=200 {
        let q = at(f64::from(i) / 200.0);
        len += norm(sub(q, prev));
        prev = q;
    }
    let n = ((len / LOOP_STEP_MM).ceil() as usize).max(2);
    (1..=n).map(|i| at(i as f64 / n as f64)).collect()
}

/// Length (mm) of the smooth path through the points `pts` (after `start`) from point `k`
/// backwards (`back`) or forwards: up to the last point before the path turns by more than
/// [`SMOOTH_TURN_DEG`] between two chords (another corner), and short of any point for which
/// `fixed` holds (a kept line's: rapids and cycles are written as programmed).
fn smooth_extent(
    pts: &[[f64; 3]],
    start: [f64; 3],
    k: usize,
    back: bool,
    fixed: &dyn Fn(usize) -> bool,
) -> f64 {
    let at = |j: isize| -> Option<[f64; 3]> {
        match j {
            -1 => Some(start),
            j if j < -1 => None,
            j => pts.get(j as usize).copied().filter(|_| !fixed(j as usize)),
        }
    };
    let step = if back { -1 } else { 1 };
    let mut len = 0.0;
    let mut prev = pts[k];
    let mut dir: Option<[f64; 3]> = None;
    let mut j = k as isize;
    loop {
        j += step;
        let Some(q) = at(j) else { break };
        let d = sub(q, prev);
        let l = norm(d);
        if l <= 0.0 {
            continue;
        }
        let u = d.map(|v| v / l);
        if let Some(w) = dir {
            let cos: f64 = (0..3).map(|i| u[i] * w[i]).sum();
            if cos < SMOOTH_TURN_DEG.to_radians().cos() {
                break;
            }
        }
        dir = Some(u);
        len += l;
        prev = q;
    }
    len
}

/// The candidate for parameters `params` (one per corner of `spots`, which are in path
/// order, at the points `corners` of the original path) on the points of `base` (with their
/// run arrays).
fn candidate(
    reference: &Reference,
    base: &Arrays,
    spots: &[CornerSpot],
    params: &[[f64; 6]],
) -> Arrays {
    let round3 = |p: [f64; 3]| p.map(|v| round_to(v, POSITION_DECIMALS));
    let mut out = Arrays {
        pts: Vec::new(),
        base_feed: Vec::new(),
        sigma: Vec::new(),
        base_len: Vec::new(),
        lines: Vec::new(),
        in_loop: Vec::new(),
    };
    let mut c = 0;
    let mut k = 0;
    let m = base.pts.len();
    while k < m {
        let Some(spot) = spots.get(c) else {
            out.push_from(base, k);
            k += 1;
            continue;
        };
        let [a, b, ..] = params[c];
        if base.sigma[k] <= spot.sigma - a {
            out.push_from(base, k);
            k += 1;
            continue;
        }
        // The loop replaces the points within (σ − a, σ + b).
        let ends = (
            reference.point_at(spot.sigma - a),
            reference.point_at(spot.sigma + b),
        );
        // A line the loop would leave without a point would be written as programmed (to
        // the corner, before the loop): it keeps the loop's start, on the path.
        let corner_line = base.lines[spot.k];
        if out.lines.last() != Some(&corner_line) {
            out.pts.push(round3(ends.0.0));
            out.base_feed.push(base.base_feed[spot.k]);
            out.sigma.push(spot.sigma - a);
            out.base_len.push(0.0);
            out.lines.push(corner_line);
            out.in_loop.push(true);
        }
        let pts = loop_points(ends.0, ends.1, spot.d_in, spot.d_out, &params[c]);
        let n = pts.len();
        let next = (spot.k + 1).min(m - 1);
        // Every point of the loop belongs to the block after the corner: that line names
        // the axis it moves, the line before named the other, so the emitter can write
        // both coordinates of every point (an axis no line has named yet is not written).
        let j = next;
        for (i, p) in pts.into_iter().enumerate() {
            let t = (i + 1) as f64 / n as f64;
            out.pts.push(round3(p));
            out.base_feed.push(base.base_feed[j]);
            out.sigma.push(spot.sigma - a + t * (a + b));
            out.base_len.push(0.0);
            out.lines.push(base.lines[j]);
            out.in_loop.push(true);
        }
        while k < m && base.sigma[k] <= spot.sigma + b + 1e-9 {
            k += 1;
        }
        c += 1;
    }
    out
}

impl Arrays {
    fn push_from(&mut self, base: &Arrays, k: usize) {
        self.pts.push(base.pts[k]);
        self.base_feed.push(base.base_feed[k]);
        self.sigma.push(base.sigma[k]);
        self.base_len.push(base.base_len[k]);
        self.lines.push(base.lines[k]);
        self.in_loop.push(false);
    }

    /// Makes the run describe these points (no dwells).
    pub(super) fn install(&self, run: &mut Run) {
        run.base_feed.clone_from(&self.base_feed);
        run.sigma.clone_from(&self.sigma);
        run.base_len.clone_from(&self.base_len);
        run.lines.clone_from(&self.lines);
        run.dwell_s.clear();
    }
}

/// Distance-weighted RMS and max (mm) of a simulation's foot distances.
pub(super) fn figures(e: &Eval) -> (f64, f64) {
    let ce: Vec<f64> = e.feet.iter().map(|(_, d)| norm(*d)).collect();
    (distance_weighted_rms(&ce, &tips_of(&e.actual)), e.max)
}

/// Searches the loops of the corners `spots` of the undistorted points `pts0`, starting from
/// the points `cur` (the main iteration's; the run's arrays describe them on entry). `orig`
/// is the original's (distance-weighted RMS, max) in mm. Returns `None` when a corner is an
/// inside corner or has no room for a loop. The run's arrays are those of the last candidate
/// tried on return: [`try_loops`] restores them.
fn search(
    run: &mut Run,
    cur: &[[f64; 3]],
    pts0: &[[f64; 3]],
    spots: &[CornerSpot],
    orig: (f64, f64),
    (share, max_weight): (f64, f64),
) -> Result<Option<Loops>, Error> {
    if spots.is_empty() || spots.iter().any(|s| !s.outside) {
        return Ok(None);
    }
    let base = Arrays {
        pts: cur.to_vec(),
        base_feed: run.base_feed.clone(),
        sigma: run.sigma.clone(),
        base_len: run.base_len.clone(),
        lines: run.lines.clone(),
        in_loop: vec![false; cur.len()],
    };
    // Room per corner: the straight legs, and half-way to the neighbouring corners.
    let mut caps = Vec::with_capacity(spots.len());
    // Stage 2's room: the straight legs, and the gap to the next corner shared with its
    // loop (`b` of one corner and `a` of the next together within 0.9 of the gap).
    let mut wide = Vec::with_capacity(spots.len());
    let mut gaps = Vec::with_capacity(spots.len());
    for (c, s) in spots.iter().enumerate() {
        let fixed = |j: usize| run.kept.contains_key(&run.lines[j]);
        let back = smooth_extent(pts0, run.start, s.k, true, &fixed);
        let fwd = smooth_extent(pts0, run.start, s.k, false, &fixed);
        let prev = if c > 0 {
            s.sigma - spots[c - 1].sigma
        } else {
            f64::INFINITY
        };
        let next = spots
            .get(c + 1)
            .map_or(f64::INFINITY, |n| n.sigma - s.sigma);
        let cap_a = (0.9 * back).min(0.5 * prev);
        let cap_b = (0.9 * fwd).min(0.5 * next);
        if cap_a < 2.0 * LOOP_STEP_MM || cap_b < 2.0 * LOOP_STEP_MM {
            return Ok(None);
        }
        caps.push((cap_a, cap_b));
        wide.push((0.9 * back.min(prev), 0.9 * fwd.min(next)));
        gaps.push(next);
    }
    let slowest_kv = run
        .machine
        .axes
        .iter()
        .take(3)
        .map(|a| a.servo.kv)
        .fold(f64::INFINITY, f64::min);
    let lag: Vec<f64> = spots
        .iter()
        .map(|s| s.feed_mm_min / 60.0 / slowest_kv)
        .collect();
    let clamp = |c: usize, p: [f64; 6]| -> [f64; 6] {
        let (ca, cb) = caps[c];
        let mut q = p;
        q[0] = q[0].clamp(LOOP_STEP_MM, ca);
        q[1] = q[1].clamp(LOOP_STEP_MM, cb);
        for v in &mut q[2..] {
            *v = v.clamp(-lag[c], 2.0 * lag[c]);
        }
        q
    };
    // Stage 2's clamp: as `clamp`, with `a` and `b` within the wide room, each against the
    // neighbouring loop's current extent (`cur`; one coordinate moves per trial).
    let clamp_wide = |c: usize, p: [f64; 6], cur: &[[f64; 6]]| -> [f64; 6] {
        let (ca, cb) = wide[c];
        let mut q = p;
        let before = if c > 0 {
            0.9 * gaps[c - 1] - cur[c - 1][1]
        } else {
            ca
        };
        let after = cur.get(c + 1).map_or(cb, |n| 0.9 * gaps[c] - n[0]);
        q[0] = q[0].clamp(LOOP_STEP_MM, ca.min(before).max(LOOP_STEP_MM));
        q[1] = q[1].clamp(LOOP_STEP_MM, cb.min(after).max(LOOP_STEP_MM));
        for v in &mut q[2..] {
            *v = v.clamp(-lag[c], 2.0 * lag[c]);
        }
        q
    };
    let limit = (1.0 + share * run.time_budget) * run.orig_periods as f64;
    let work = std::cell::Cell::new(0usize);
    let simulations = std::cell::Cell::new(0usize);
    let spent = || work.get() >= LOOP_WORK_PERIODS;
    let count = |e: &Eval| {
        work.set(work.get() + e.actual[0].len());
        simulations.set(simulations.get() + 1);
    };
    let score = |run: &Run, e: &Eval| objective(run, e, orig, limit, max_weight);
    let score_full = |run: &Run, e: &Eval| objective(run, e, orig, full_limit(run), max_weight);
    let eval = |run: &mut Run, params: &[[f64; 6]]| -> Result<Option<(f64, Arrays, Eval)>, Error> {
        if spent() {
            return Ok(None);
        }
        let cand = candidate(&run.reference, &base, spots, params);
        cand.install(run);
        let e = run.evaluate(&cand.pts)?;
        count(&e);
        Ok(Some((score(run, &e), cand, e)))
    };
    // Stage 1: one shape for all corners, in units of each corner's lag length.
    let shared = |u: &[f64; 4]| -> Vec<[f64; 6]> {
        (0..spots.len())
            .map(|c| {
                let l = lag[c];
                clamp(c, [u[0] * l, u[1] * l, u[2] * l, u[3] * l, 0.0, 0.0])
            })
            .collect()
    };
    let mut best: Option<(f64, Arrays, Eval, Vec<[f64; 6]>)> = None;
    let mut u_best = [0.5, 0.9, 0.5, 0.05];
    let mut grid: Vec<(f64, [f64; 4])> = Vec::new();
    for a in [0.1, 0.5, 0.9] {
        for (b, o1) in [(0.9, 0.3), (0.9, 0.6), (0.6, 0.3), (1.2, 0.6), (0.9, 0.9)] {
            let u = [a, b, o1, 0.05];
            let params = shared(&u);
            if let Some((s, cand, e)) = eval(run, &params)? {
                grid.push((s, u));
                if best.as_ref().is_none_or(|b| s < b.0) {
                    best = Some((s, cand, e, params));
                    u_best = u;
                }
            }
        }
    }
    let mut step = 0.1;
    while step > 0.01 {
        let mut improved = false;
        for i in 0..4 {
            for sgn in [1.0, -1.0] {
                let mut u = u_best;
                u[i] += sgn * step;
                let params = shared(&u);
                let Some((s, cand, e)) = eval(run, &params)? else {
                    break;
                };
                if best.as_ref().is_none_or(|b| s < b.0 - 1e-9) {
                    best = Some((s, cand, e, params));
                    u_best = u;
                    improved = true;
                    break;
                }
            }
        }
        if !improved {
            step *= 0.5;
        }
        if spent() {
            break;
        }
    }
    let Some(best) = best else {
        return Ok(None);
    };
    // Stages 2 and 3 (module `descent`) from the best shared shape and from the two next
    // best starting shapes: the descents end in different local minima.
    let window = |run: &Run, e: &Eval| -> Vec<f64> {
        let sc = super::corners::score(&run.reference, spots, e);
        sc.iter().zip(spots).map(|(s, c)| s.objective(c)).collect()
    };
    let stage = descent::Stage {
        spots,
        lag: &lag,
        eval: &eval,
        clamp: &clamp_wide,
        window: &window,
    };
    grid.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut starts = vec![best.3.clone()];
    for (_, u) in &grid {
        if starts.len() >= DESCENTS {
            break;
        }
        if *u != u_best {
            starts.push(shared(u));
        }
    }
    // Each start descends twice: with the room between neighbouring corners shared (one
    // loop may take more of a gap than the other) and with each loop kept to its half of
    // it. Neither is better everywhere: the 2 mm staircase at F 2000, kv 40, ends at 0.282×
    // RMS with the halves and 0.318× shared; at F 3000, kv 30, at 0.327× and 0.292×.
    let halves = |c: usize, p: [f64; 6], _: &[[f64; 6]]| clamp(c, p);
    let kept_to_halves = descent::Stage {
        clamp: &halves,
        ..stage
    };
    let mut found: Option<descent::Best> = None;
    'starts: for params in starts {
        for st in [&stage, &kept_to_halves] {
            let Some((s, cand, e)) = eval(run, &params)? else {
                break 'starts;
            };
            let end = st.descend(run, (s, cand, e, params.clone()))?;
            if found.as_ref().is_none_or(|b| end.0 < b.0) {
                found = Some(end);
            }
        }
    }
    let mut best = found.unwrap_or(best);
    let bounded = spent();
    // Stage 4 (module `settle`): the points between the loops, for the loops' timing.
    let fixed: Vec<bool> = best
        .1
        .lines
        .iter()
        .map(|l| run.kept.contains_key(l))
        .collect();
    settle::settle(run, &mut best, &score, &|k| fixed[k], &count)?;
    // Stage 5 (module `lateral`): every point near a corner, sideways, within the whole
    // duration budget.
    let m = best.1.pts.len();
    best.0 = score_full(run, &best.2);
    let still = |k: usize| k + 1 == m || fixed[k];
    lateral::lateral(run, &mut best, spots, &score_full, &still, &count)?;
    let (_, cand, e, _) = best;
    Ok(Some(Loops {
        arrays: cand,
        eval: e,
        simulations: simulations.get(),
        bounded,
        second: share < 1.0,
    }))
}

mod choose;
mod descent;
mod lateral;
mod settle;

pub(super) use choose::{better, original_figures, try_loops};
use choose::{full_limit, objective};

#[cfg(test)]
mod tests;
