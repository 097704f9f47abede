//! Smooth loops at outside corners (issue 24 item 4, "small overshoot loops at outside
//! corners"): an alternative to the corner stage's three split points.
//!
//! Each corner the junction limit slows is replaced, from `a` mm before it to `b` mm after
//! it on the original path, by G01 points on a cubic Bézier curve (equal steps of its
//! parameter, as many as make the chords [`LOOP_STEP_MM`] long on average)
//! whose control points lie beyond the corner: `C1 = c + o1·d_in − w1·d_out` and
//! `C2 = c + w2·d_in − o2·d_out` (`c` the corner, `d_in`/`d_out` the unit tangents of the path
//! into and out of it). The command is carried on past the corner along the incoming
//! direction and swings back onto the outgoing leg ahead of it, so the lagging tool turns at
//! the corner. A smooth loop of short chords is run at the speed its curvature allows (the
//! interpolator's junction rule over the path of one period, `√(max_accel·R)`), well above
//! the few mm/s at which the junction limit lets a sharp 90° turn pass, so the time the
//! braking lag costs at the corner comes back.
//!
//! The six numbers per corner are found by pattern search on the exact interpolation and
//! simulation (the same [`Run::evaluate`] as the other stages): first one set shared by
//! all corners, in units of the servo's lag length `λ = v/kv` (the feed over the slowest
//! position-loop gain; 15 starting shapes, then a pattern search), then each corner's own,
//! coordinate by coordinate, halving the step, and starting again from the largest step
//! (at most twice) while a round still improves.
//! The objective is the distance-weighted RMS plus 0.3× the max, each against the original's,
//! plus a steep penalty on time beyond the duration budget
//! ([`super::PredistortOptions::max_duration_ratio`]). The work is bounded by
//! [`LOOP_WORK_PERIODS`] simulated periods.
//!
//! Only outside corners loop (the free side of the path); a program with an inside corner
//! (G41/G42 material outside the turn) keeps the three-point stage's answer.

use super::corners::CornerSpot;
use super::measure::{distance_weighted_rms, tips_of};
use super::run::{Eval, Run, norm, round_to, sub};
use super::{Error, POSITION_DECIMALS};

/// Mean spacing (mm) of the G01 points along a loop (20 µm; the points are at equal steps of
/// the curve's parameter): the chords stay within a fraction of a micrometre of the curve,
/// and at the loops' speeds (tens of mm/s) each chord lasts about a period, so the
/// interpolator's junction rule sees the curve's own curvature.
pub const LOOP_STEP_MM: f64 = 0.02;

/// Work bound of the loop search: simulated interpolation periods (all candidates' whole
/// programs together), 4,000,000 (some 4,000 simulations of a 1 s program).
pub const LOOP_WORK_PERIODS: usize = 4_000_000;

/// Weight of the max ratio in the search's objective (the distance-weighted RMS ratio has 1).
const MAX_WEIGHT: f64 = 0.3;

/// Penalty per unit of duration ratio beyond the budget.
const LATE_WEIGHT: f64 = 100.0;

/// What the loop search found: the points, the [`Run`] arrays that follow them, their
/// simulation.
pub(super) struct Loops {
    pub arrays: Arrays,
    pub eval: Eval,
    /// Simulations run.
    pub simulations: usize,
}

/// Per-point arrays of a candidate (the [`Run`] fields that follow the points).
pub(super) struct Arrays {
    pub pts: Vec<[f64; 3]>,
    base_feed: Vec<f64>,
    sigma: Vec<f64>,
    base_len: Vec<f64>,
    pub lines: Vec<usize>,
}

/// The loop of one corner for parameters `p` = `[a, b, o1, o2, w1, w2]` (mm): points from
/// the curve's start (excluded: it is the last point kept on the incoming leg) to its end.
fn loop_points(c: [f64; 3], d_in: [f64; 3], d_out: [f64; 3], p: &[f64; 6]) -> Vec<[f64; 3]> {
    let [a, b, o1, o2, w1, w2] = *p;
    let s: [f64; 3] = std::array::from_fn(|d| c[d] - a * d_in[d]);
    let e: [f64; 3] = std::array::from_fn(|d| c[d] + b * d_out[d]);
    let c1: [f64; 3] = std::array::from_fn(|d| c[d] + o1 * d_in[d] - w1 * d_out[d]);
    let c2: [f64; 3] = std::array::from_fn(|d| c[d] + w2 * d_in[d] - o2 * d_out[d]);
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

/// Straight length (mm) of the path through the points `pts` (after `start`) from point
/// `k` backwards (`back`) or forwards along the unit tangent `u`: up to the last point within
/// 1 µm of the line through point `k`, and short of any point for which `fixed` holds (a
/// kept line's: rapids and cycles are written as programmed).
fn straight_extent(
    pts: &[[f64; 3]],
    start: [f64; 3],
    k: usize,
    u: [f64; 3],
    back: bool,
    fixed: &dyn Fn(usize) -> bool,
) -> f64 {
    let c = pts[k];
    let mut best = 0.0;
    let mut j = k as isize;
    loop {
        j += if back { -1 } else { 1 };
        let q = match j {
            -1 => start,
            j if j < -1 => break,
            j => match pts.get(j as usize) {
                Some(_) if fixed(j as usize) => break,
                Some(q) => *q,
                None => break,
            },
        };
        let d = sub(q, c);
        let along_u: f64 = (0..3).map(|i| d[i] * u[i]).sum();
        let along = if back { -along_u } else { along_u };
        let off = norm(std::array::from_fn(|i| d[i] - along_u * u[i]));
        if along <= best || off > 1e-3 {
            break;
        }
        best = along;
    }
    best
}

/// The candidate for parameters `params` (one per corner of `spots`, which are in path
/// order, at the points `corners` of the original path) on the points of `base` (with their
/// run arrays).
fn candidate(
    base: &Arrays,
    spots: &[CornerSpot],
    corners: &[[f64; 3]],
    params: &[[f64; 6]],
) -> Arrays {
    let round3 = |p: [f64; 3]| p.map(|v| round_to(v, POSITION_DECIMALS));
    let mut out = Arrays {
        pts: Vec::new(),
        base_feed: Vec::new(),
        sigma: Vec::new(),
        base_len: Vec::new(),
        lines: Vec::new(),
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
        let pts = loop_points(corners[c], spot.d_in, spot.d_out, &params[c]);
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
) -> Result<Option<Loops>, Error> {
    if spots.is_empty() || spots.iter().any(|s| !s.outside) {
        return Ok(None);
    }
    let corners: Vec<[f64; 3]> = spots.iter().map(|s| pts0[s.k]).collect();
    let base = Arrays {
        pts: cur.to_vec(),
        base_feed: run.base_feed.clone(),
        sigma: run.sigma.clone(),
        base_len: run.base_len.clone(),
        lines: run.lines.clone(),
    };
    // Room per corner: the straight legs, and half-way to the neighbouring corners.
    let mut caps = Vec::with_capacity(spots.len());
    for (c, s) in spots.iter().enumerate() {
        let fixed = |j: usize| run.kept.contains_key(&run.lines[j]);
        let back = straight_extent(pts0, run.start, s.k, s.d_in, true, &fixed);
        let fwd = straight_extent(pts0, run.start, s.k, s.d_out, false, &fixed);
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
    let limit = (1.0 + run.time_budget) * run.orig_periods as f64;
    let work = std::cell::Cell::new(0usize);
    let simulations = std::cell::Cell::new(0usize);
    let spent = || work.get() >= LOOP_WORK_PERIODS;
    let eval = |run: &mut Run, params: &[[f64; 6]]| -> Result<Option<(f64, Arrays, Eval)>, Error> {
        if spent() {
            return Ok(None);
        }
        let cand = candidate(&base, spots, &corners, params);
        cand.install(run);
        let e = run.evaluate(&cand.pts)?;
        work.set(work.get() + e.actual[0].len());
        simulations.set(simulations.get() + 1);
        let (dw, max) = figures(&e);
        let late = (e.periods as f64 / limit - 1.0).max(0.0) * (1.0 + run.time_budget);
        let score =
            dw / orig.0.max(1e-12) + MAX_WEIGHT * max / orig.1.max(1e-12) + LATE_WEIGHT * late;
        Ok(Some((score, cand, e)))
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
    for a in [0.1, 0.5, 0.9] {
        for (b, o1) in [(0.9, 0.3), (0.9, 0.6), (0.6, 0.3), (1.2, 0.6), (0.9, 0.9)] {
            let u = [a, b, o1, 0.05];
            let params = shared(&u);
            if let Some((s, cand, e)) = eval(run, &params)? {
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
    let Some(mut best) = best else {
        return Ok(None);
    };
    // Stage 2: each corner's own six numbers. One coordinate moves at every corner at once
    // and each corner keeps the move where its own window's objective fell (the windows
    // are apart: one simulation judges all corners), if the program's objective falls too.
    let window = |run: &Run, e: &Eval| -> Vec<f64> {
        let sc = super::corners::score(&run.reference, spots, e);
        sc.iter().zip(spots).map(|(s, c)| s.objective(c)).collect()
    };
    let mut scores = window(run, &best.2);
    let min_lag = lag.iter().copied().fold(f64::INFINITY, f64::min);
    let mut rounds = 0;
    let mut round_start = best.0;
    let mut step = 0.05 * min_lag;
    loop {
        if step <= 0.003 * min_lag {
            rounds += 1;
            if rounds >= 3 || best.0 >= round_start - 1e-9 {
                break;
            }
            round_start = best.0;
            step = 0.05 * min_lag;
        }
        if spent() {
            break;
        }
        let mut improved = false;
        for i in 0..6 {
            for sgn in [1.0, -1.0] {
                let trial: Vec<[f64; 6]> = (0..spots.len())
                    .map(|c| {
                        let mut p = best.3[c];
                        p[i] += sgn * step;
                        clamp(c, p)
                    })
                    .collect();
                let Some((s_t, cand_t, e_t)) = eval(run, &trial)? else {
                    break;
                };
                let sc_t = window(run, &e_t);
                let take: Vec<bool> = (0..spots.len())
                    .map(|c| trial[c] != best.3[c] && sc_t[c] < scores[c] * (1.0 - 1e-6))
                    .collect();
                if !take.iter().any(|&t| t) {
                    continue;
                }
                let (s_c, cand_c, e_c, params) = if take.iter().all(|&t| t) {
                    (s_t, cand_t, e_t, trial)
                } else {
                    let params: Vec<[f64; 6]> = (0..spots.len())
                        .map(|c| if take[c] { trial[c] } else { best.3[c] })
                        .collect();
                    let Some((s, cand, e)) = eval(run, &params)? else {
                        break;
                    };
                    (s, cand, e, params)
                };
                if s_c < best.0 - 1e-9 {
                    scores = window(run, &e_c);
                    best = (s_c, cand_c, e_c, params);
                    improved = true;
                }
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    let (_, cand, e, _) = best;
    Ok(Some(Loops {
        arrays: cand,
        eval: e,
        simulations: simulations.get(),
    }))
}

/// The original's distance-weighted RMS and max (mm) from its contour errors `ce` (mm per
/// period) and simulated axes `actual`: the scale of the loop search's objective.
pub(super) fn original_figures(ce: &[f64], actual: &[Vec<f64>]) -> (f64, f64) {
    let max = ce.iter().fold(0.0f64, |m, v| m.max(*v));
    (distance_weighted_rms(ce, &tips_of(actual)), max)
}

/// [`search`] on the points `cur` (the run's arrays describe them), with the run's arrays
/// (and dwells) restored afterwards.
pub(super) fn try_loops(
    run: &mut Run,
    cur: &[[f64; 3]],
    pts0: &[[f64; 3]],
    spots: &[CornerSpot],
    orig: (f64, f64),
) -> Result<Option<Loops>, Error> {
    let saved = (
        run.base_feed.clone(),
        run.sigma.clone(),
        run.base_len.clone(),
        run.lines.clone(),
        run.dwell_s.clone(),
    );
    let out = search(run, cur, pts0, spots, orig);
    (
        run.base_feed,
        run.sigma,
        run.base_len,
        run.lines,
        run.dwell_s,
    ) = saved;
    out
}

/// Whether the loops `lp` beat the other stages' answer `other`: a lower sum of the
/// distance-weighted RMS and max ratios to the original's (`orig`), within the duration
/// budget, and no corner's tool beyond the path into the material by more than its cap
/// (`gouge_cap`, mm, per corner of `spots`).
pub(super) fn better(
    run: &Run,
    lp: &Loops,
    other: &Eval,
    spots: &[CornerSpot],
    gouge_cap: &[f64],
    orig: (f64, f64),
) -> bool {
    let score = |e: &Eval| {
        let (dw, max) = figures(e);
        dw / orig.0.max(1e-12) + max / orig.1.max(1e-12)
    };
    let in_time = lp.eval.periods as f64 <= (1.0 + run.time_budget) * run.orig_periods as f64;
    let gouges = super::corners::score(&run.reference, spots, &lp.eval);
    let clean = gouges.iter().zip(gouge_cap).all(|(s, cap)| s.gouge <= *cap);
    in_time && clean && score(&lp.eval) < score(other)
}

#[cfg(test)]
mod tests;
