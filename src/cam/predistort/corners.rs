//! The corner stage of the pre-distortion (issue 24): at every corner where the machine's
//! junction limit slows the original below its feed, the corner point `C` of the G01 points
//! becomes three: `Q = C − L·d_in` (the end of the braking, `L` before the corner),
//! `P_in = C + δ_in·d_in` (the incoming move carried on past the corner) and
//! `P_out = C + δ_out·d_out` (the outgoing move entered ahead of the corner), `d_in`, `d_out`
//! the original path's unit tangents into and out of the corner. The block `Q → P_in` runs
//! at the fastest speed the original itself had over those last `L` mm (the junction limit
//! already forced it there), never faster than the programmed feed.
//!
//! Why. A servo of gain `kv` with velocity feed-forward `kff` lags its command by about
//! `τ = (1 − kff)/kv` seconds; its inverse leads, `u ≈ r + τ·ṙ + …`. At a corner `ṙ` turns
//! from `v_j·d_in` to `v_j·d_out` (`v_j` the junction speed), so the command that makes the
//! tool tip turn the corner runs `τ·v_j` past it along `d_in`, then jumps to `τ·v_j` ahead of
//! it along `d_out`: points moved forward along the path so that the lag is absorbed before
//! the corner, with a small overshoot chord outside the corner between them. But the braking
//! into the corner takes the interpolator about as long as the servo's time constant, so the
//! tool arrives still lagging by its braking; ending the braking `L` before the corner lets
//! the lag settle to `τ·v_j` first. The jerk-limited interpolator cannot replay the exact
//! inverse (its blocks start and end at zero acceleration, its junctions turn within
//! `max_accel·period`), so `(δ_in, δ_out, L)` of each corner are found by a pattern search on
//! the service's own interpolation and simulation, all corners at once, each judged on its
//! own stretch of path (the samples whose foot lies within its window): the
//! distance-weighted sum of squared contour errors plus [`MAX_WEIGHT_MM`] times the squared
//! largest one (at an inside corner, plus [`GOUGE_WEIGHT_MM`] times the squared gouge beyond
//! 90 % of the limit). A move is kept only when it lowers that, keeps the tool out of the
//! material and keeps the corner's extra time within its share of the duration budget ([`SEARCH_SHARE`]; and the
//! whole program within it).
//!
//! Material side. At an inside corner (the material outside the turn, as in a pocket) the
//! tool may go no more than [`GOUGE_LIMIT_MM`] beyond the original path on the outer side of
//! the turn, so the carried-past command may not make the tool overshoot. At an outside
//! corner (the material inside the turn, as around a boss) the outer side is free: the
//! command loops out there and the tool's overshoot is error like any other, counted in the
//! figures; a move may not make the tool cut deeper into the inside of the turn than the
//! search's current point does (so never deeper than at its start; letting a move cut back
//! down to the start's depth was tried and is no better on the corner table). The program
//! says which (G41: material right of the path, G42: left, see
//! [`corner_is_outside`]); without G41/G42 every corner is read as an outside corner (the rule
//! for an unknown side: the program is taken as an outside contour, where a finishing pass's
//! sharp corners usually are; a pocket's corners are rounded by its tool).
//!
//! Stops at inside corners. With the outer side closed, no loop can turn the tool at the
//! junction speed without cutting the corner: the servo needs about `τ·v_j` of path to turn
//! its velocity. An inside corner's search has a fourth coordinate, a stop at `P_in` (a G4
//! dwell of whole milliseconds, at most [`MAX_STOP_S`]), tried first: the command halts at the
//! corner, the tool comes to rest on the incoming line (the cascade's step response has no
//! overshoot along the path) and leaves from rest along the outgoing one, so the turn cuts
//! nothing; the time it takes is held to the corner's share of the budget like any other
//! move. A stopping corner takes the points of its window as they lie on the original path
//! (the earlier iteration's lateral corrections there were for a corner turned at speed and
//! would now push the tool into the material). This is the machinist's exact stop at a sharp
//! inside corner; the same 10 mm pocket at F 2000 on kv 40 with 40 ms dwells and no
//! pre-distortion has 3.0 µm distance-weighted RMS against 17.3 µm without them.
//!
//! Reference: the servo lag and its feed-forward inverse, Zhang & Chen 2025 §3; the search,
//! Hooke & Jeeves 1961 (pattern search with step halving).

use super::measure::{outward_offset, path_weights, tips_of};
use super::reference::Reference;
use super::{BREAK_RAD, POSITION_DECIMALS};
use super::{Error, Eval, MaterialSide, Run, norm, round_to, sub};

/// Largest distance (mm) the simulated tool tip may go beyond the original path on the
/// outer side of a corner (issue 24: 1 µm); the search keeps a 10 % margin.
pub const GOUGE_LIMIT_MM: f64 = 1e-3;

/// Fraction of the duration budget (`max_duration_ratio − 1` of the original program's
/// duration, [`super::PredistortOptions`]) the corner stage may spend, all corners together:
/// 0.8 (0.12 of the duration at the default ratio 1.15); the corner-window ILC may take the
/// rest up to `super::ilc::ILC_SHARE`.
pub const SEARCH_SHARE: f64 = 0.8;

/// Arc length (mm) on either side of a corner within which the outward offset counts as a
/// gouge of that corner.
const GOUGE_ARC_MM: f64 = 1.0;

/// First step of the search (mm; `L` takes five times it) and the step at which it stops.
const STEP0_MM: f64 = 0.02;
const STEP_MIN_MM: f64 = 4e-4;

/// Weight (mm of path) of the squared largest error in a corner's objective.
pub const MAX_WEIGHT_MM: f64 = 2.0;

/// Longest braking lead `L`, mm.
const MAX_LEAD_MM: f64 = 2.0;

/// Most search rounds (up to two simulations each).
const MAX_ROUNDS: usize = 200;

/// One corner the stage works on.
pub(super) struct CornerSpot {
    /// Index of the corner's point among the points before the stage.
    pub k: usize,
    /// Unit tangents of the original path into and out of the corner.
    pub d_in: [f64; 3],
    pub d_out: [f64; 3],
    /// Unit vector into the turn.
    pub inside: [f64; 3],
    /// An outside corner: the material lies inside the turn, the outer side is free (the
    /// command may loop out there); otherwise an inside corner, the material outside the turn.
    pub outside: bool,
    /// Turn of the path, rad.
    pub turn_rad: f64,
    /// Largest |δ| (mm).
    pub cap_mm: f64,
    /// Largest braking lead `L` (mm).
    pub cap_lead_mm: f64,
    /// Programmed feed of the block ending at the corner, mm/min.
    pub feed_mm_min: f64,
    /// Arc parameter of the corner on the reference and the window of samples it is judged
    /// on, mm.
    pub sigma: f64,
    pub lo: f64,
    pub hi: f64,
    /// Junction speed limit of the original at the corner, mm/s.
    pub v_junction: f64,
    /// Source line of the block ending at the corner.
    pub line: usize,
}

/// How one corner fared in one simulation.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct CornerScore {
    /// Distance-weighted sum of squared errors in the window, mm³.
    pub sum_sq: f64,
    /// Path length of the window's samples, mm.
    pub len: f64,
    /// Largest error in the window, mm.
    pub max: f64,
    /// Largest outward offset near the corner, mm (≤ 0 when none).
    pub gouge: f64,
    /// Periods the command spends on the blocks around the corner.
    pub periods: usize,
}

/// Weight (mm) of the squared excess of an inside corner's gouge over 90 % of
/// [`GOUGE_LIMIT_MM`] in its objective: large, so that the search first takes the tool back
/// inside the limit where an earlier stage left it beyond.
const GOUGE_WEIGHT_MM: f64 = 1e4;

impl CornerScore {
    /// The search's objective (mm³) at corner `spot`.
    pub(super) fn objective(&self, spot: &CornerSpot) -> f64 {
        let excess = if spot.outside {
            0.0
        } else {
            (self.gouge - 0.9 * GOUGE_LIMIT_MM).max(0.0)
        };
        self.sum_sq + MAX_WEIGHT_MM * self.max * self.max + GOUGE_WEIGHT_MM * excess * excess
    }
}

/// The corners of the points `idx` (reference knot of each point; `idx[0]` is the start)
/// whose original junction limit `limits` (mm/s) lies below the feed (`feeds`, mm/min).
/// `side(line)` is the material side of the block of a source line, when the program says
/// (G41/G42); corners of lines without one are outside corners ([`corner_is_outside`]).
pub(super) fn find_corners(
    reference: &Reference,
    idx: &[usize],
    pts: &[[f64; 3]],
    start: [f64; 3],
    limits: &[(f64, usize)],
    feeds: &[f64],
    side: &dyn Fn(usize) -> Option<MaterialSide>,
) -> Vec<CornerSpot> {
    let m = pts.len();
    let knots = &reference.knots;
    let mut out: Vec<CornerSpot> = Vec::new();
    for k in 0..m.saturating_sub(1) {
        let ki = idx[k + 1];
        if !reference.corner[ki] || ki == 0 || ki + 1 >= knots.len() {
            continue;
        }
        let need = feeds[k].min(feeds[k + 1]) / 60.0;
        if limits[k].0 >= 0.98 * need {
            continue;
        }
        let unit = |a: [f64; 3]| {
            let l = norm(a);
            a.map(|v| v / l.max(1e-300))
        };
        let d_in = unit(sub(knots[ki], knots[ki - 1]));
        let d_out = unit(sub(knots[ki + 1], knots[ki]));
        let cos = (0..3).map(|d| d_in[d] * d_out[d]).sum::<f64>();
        let turn_rad = cos.clamp(-1.0, 1.0).acos();
        if turn_rad < BREAK_RAD {
            continue;
        }
        let inside = unit(std::array::from_fn(|d| d_out[d] - d_in[d]));
        let prev = if k == 0 { start } else { pts[k - 1] };
        let len_in = norm(sub(pts[k], prev));
        let len_out = norm(sub(pts[k + 1], pts[k]));
        let cap_mm = 0.5f64.min(0.45 * len_in).min(0.45 * len_out);
        let cap_lead_mm = MAX_LEAD_MM.min(0.9 * len_in);
        let sigma = reference.cum[ki];
        let half = (need * 0.15).clamp(1.0, 10.0);
        let line = reference.line[ki];
        out.push(CornerSpot {
            k,
            d_in,
            d_out,
            inside,
            outside: corner_is_outside(d_in, d_out, side(line)),
            turn_rad,
            cap_mm,
            cap_lead_mm,
            feed_mm_min: feeds[k],
            sigma,
            lo: sigma - half,
            hi: sigma + half,
            v_junction: limits[k].0,
            line,
        });
    }
    // Windows of neighbouring corners meet halfway.
    for c in 1..out.len() {
        let mid = 0.5 * (out[c - 1].sigma + out[c].sigma);
        if out[c - 1].hi > mid {
            out[c - 1].hi = mid;
        }
        if out[c].lo < mid {
            out[c].lo = mid;
        }
    }
    out
}

/// The points with each corner `k` split into `Q`, `P_in`, `P_out` for the parameters `theta`
/// (δ_in, δ_out, L per corner, mm); corner `c`'s `Q` lands at index `k + 2c`. `Q` lies on the
/// chord from the point before.
pub(super) fn split_points(
    start: [f64; 3],
    base: &[[f64; 3]],
    corners: &[CornerSpot],
    theta: &[[f64; 4]],
) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(base.len() + 2 * corners.len());
    let mut c = 0;
    for (k, p) in base.iter().enumerate() {
        if c < corners.len() && corners[c].k == k {
            let s = &corners[c];
            let [di, dout, lead, _] = theta[c];
            let prev = if k == 0 { start } else { base[k - 1] };
            let len = norm(sub(*p, prev)).max(1e-12);
            let f = (lead / len).min(1.0);
            let r = |v: f64| round_to(v, POSITION_DECIMALS);
            out.push(std::array::from_fn(|d| r(p[d] + f * (prev[d] - p[d]))));
            out.push(std::array::from_fn(|d| r(p[d] + di * s.d_in[d])));
            out.push(std::array::from_fn(|d| r(p[d] + dout * s.d_out[d])));
            c += 1;
        } else {
            out.push(*p);
        }
    }
    out
}

/// Programmed feeds (mm/min) of the split points for `theta`: `base` (already split by
/// [`split_values`]) with each `P_in`'s block at the original's largest speed over the last
/// `L` mm before the corner (at least its junction speed, at most the programmed feed).
pub(super) fn split_feeds(
    reference: &Reference,
    base: &[f64],
    corners: &[CornerSpot],
    theta: &[[f64; 4]],
) -> Vec<f64> {
    let mut out = base.to_vec();
    for (c, s) in corners.iter().enumerate() {
        let v = reference.max_speed(s.sigma - theta[c][2], s.sigma);
        let f = (60.0 * v * (1.0 + 1e-6)).max(60.0 * s.v_junction);
        out[s.k + 2 * c + 1] = super::ceil_to(f.min(s.feed_mm_min), super::FEED_DECIMALS);
    }
    out
}

/// Per-point data `v` (feeds, lengths, lines, arc parameters) for the split points: `Q`
/// keeps point `k`'s, `P_in` and `P_out` take `after(k)`.
pub(super) fn split_values<T: Copy>(
    v: &[T],
    corners: &[CornerSpot],
    after: impl Fn(usize) -> [T; 2],
) -> Vec<T> {
    let mut out = Vec::with_capacity(v.len() + 2 * corners.len());
    let mut c = 0;
    for (k, x) in v.iter().enumerate() {
        out.push(*x);
        if c < corners.len() && corners[c].k == k {
            out.extend(after(k));
            c += 1;
        }
    }
    out
}

/// Whether a corner turning from `d_in` to `d_out` (unit tangents) is an outside corner (the
/// material inside the turn, the outer side free): with the material side known (G41: tool
/// left of the path, material right; G42: material left), when the turn, seen in the XY
/// plane, points towards the material; without it, always (the rule of the module docs).
/// A turn that is not mostly in the XY plane (|sin| of its XY part below half its own) with a
/// side given counts as an inside corner, the cautious reading.
pub(super) fn corner_is_outside(
    d_in: [f64; 3],
    d_out: [f64; 3],
    side: Option<MaterialSide>,
) -> bool {
    let Some(side) = side else {
        return true;
    };
    let cross_z = d_in[0] * d_out[1] - d_in[1] * d_out[0];
    let cos = (0..3)
        .map(|d| d_in[d] * d_out[d])
        .sum::<f64>()
        .clamp(-1.0, 1.0);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    if cross_z.abs() < 0.5 * sin {
        return false;
    }
    let left_turn = cross_z > 0.0;
    left_turn == (side == MaterialSide::Left)
}

/// Signed distance (mm) of a tool tip beyond the original path into the material side of
/// corner `c` ([`outward_offset`] at an inside corner, its negative, the depth cut into the
/// turn, at an outside corner); positive values are gouges.
pub(super) fn material_offset(reference: &Reference, c: &CornerSpot, s: f64, e: [f64; 3]) -> f64 {
    let out = outward_offset(reference, s, e, c.inside);
    if c.outside { -out } else { out }
}

/// The corner (index) whose window holds the arc parameter `s`, if any.
fn window_of(corners: &[CornerSpot], s: f64) -> Option<usize> {
    let c = corners.partition_point(|c| c.hi < s);
    (c < corners.len() && s >= corners[c].lo).then_some(c)
}

/// Largest outward offset (mm) of the feet `feet` within [`GOUGE_ARC_MM`] of the corner whose
/// window holds them (module docs; ≤ 0 when none).
pub(super) fn gouge(
    reference: &Reference,
    corners: &[CornerSpot],
    feet: &[(f64, [f64; 3])],
) -> f64 {
    let mut g = 0.0f64;
    for (s, e) in feet {
        if let Some(c) = window_of(corners, *s)
            && (s - corners[c].sigma).abs() <= GOUGE_ARC_MM
        {
            g = g.max(material_offset(reference, &corners[c], *s, *e));
        }
    }
    g
}

/// Scores every corner on one simulation `e` of the split points.
pub(super) fn score(reference: &Reference, corners: &[CornerSpot], e: &Eval) -> Vec<CornerScore> {
    let mut out = vec![CornerScore::default(); corners.len()];
    if corners.is_empty() {
        return out;
    }
    let tips = tips_of(&e.actual);
    let w = path_weights(&tips);
    for (i, (s, err)) in e.feet.iter().enumerate() {
        let Some(c) = window_of(corners, *s) else {
            continue;
        };
        let d2 = err.iter().map(|v| v * v).sum::<f64>();
        let sc = &mut out[c];
        sc.sum_sq += w[i] * d2;
        sc.len += w[i];
        sc.max = sc.max.max(d2.sqrt());
        if (s - corners[c].sigma).abs() <= GOUGE_ARC_MM {
            let g = material_offset(reference, &corners[c], *s, *err);
            sc.gouge = sc.gouge.max(g);
        }
    }
    // Periods on the blocks from the one ending before Q to the one ending after P_out
    // (block b carries line b + 1).
    for (c, spot) in corners.iter().enumerate() {
        let q = spot.k + 2 * c;
        let first = q as u32; // line of the block ending at the point before Q
        let last = q as u32 + 4;
        out[c].periods = e.line.iter().filter(|&&l| l >= first && l <= last).count();
    }
    out
}

/// Outcome of the corner stage.
pub(super) struct CornerResult {
    /// Scores with all δ zero and at the end.
    pub before: Vec<CornerScore>,
    pub after: Vec<CornerScore>,
    /// Trials refused for a gouge and for time, per corner.
    pub refused_gouge: Vec<usize>,
    pub refused_time: Vec<usize>,
    /// Simulations run.
    pub simulations: usize,
}

/// Search directions in `(δ_in, δ_out, L, stop)` at an outside corner.
const DIRS: [[f64; 4]; 6] = [
    [0.0, 0.0, 5.0, 0.0],
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, -5.0, 0.0],
    [-1.0, 0.0, 0.0, 0.0],
    [0.0, -1.0, 0.0, 0.0],
];

/// Search directions at an inside corner: its stop first (a stop with the command carried
/// past the corner would park the tool beyond it, in the material).
const DIRS_INSIDE: [[f64; 4]; 8] = [
    [0.0, 0.0, 0.0, 1.0],
    [0.0, 0.0, 5.0, 0.0],
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 0.0, -1.0],
    [0.0, 0.0, -5.0, 0.0],
    [-1.0, 0.0, 0.0, 0.0],
    [0.0, -1.0, 0.0, 0.0],
];

/// Seconds of stop at an inside corner per mm of the search's fourth coordinate (its first
/// step, 0.02, is a 20 ms stop).
const STOP_S_PER_MM: f64 = 1.0;

/// Longest stop at an inside corner, s.
pub const MAX_STOP_S: f64 = 0.25;

/// The stop (s, whole milliseconds, as `G4 P<ms>` writes it) of the search's fourth
/// coordinate `x` (mm-equivalent).
fn stop_s(x: f64) -> f64 {
    (x * STOP_S_PER_MM * 1e3).round().max(0.0) / 1e3
}

/// Dwell (s) of each of the `m` split points for `theta`: the stop of each inside corner at
/// its `P_in` (the end of the incoming move), 0 elsewhere.
pub(super) fn split_dwells(m: usize, corners: &[CornerSpot], theta: &[[f64; 4]]) -> Vec<f64> {
    let mut out = vec![0.0; m];
    for (c, s) in corners.iter().enumerate() {
        if let Some(d) = out.get_mut(s.k + 2 * c + 1) {
            *d = stop_s(theta[c][3]);
        }
    }
    out
}

/// What [`search`] returns: its outcome, the split points, their programmed feeds (mm/min,
/// as [`Run::evaluate_with`] takes them), their dwells (s) and their simulation.
pub(super) type Searched = (CornerResult, Vec<[f64; 3]>, Vec<f64>, Vec<f64>, Eval);

/// Pattern search of `(δ_in, δ_out, L)` of every corner (module docs) on the points `base`,
/// evaluated by `run` (whose per-point data are already split). `orig_periods` is the
/// original program's length in periods.
///
/// An inside corner that stops takes the points of its window from `undistorted` (the
/// points on the original path, arc parameters `sigma`) instead of `base`: the tool leaves
/// the corner from rest along a straight move, where the earlier iteration's lateral
/// corrections of the corner's cut would only push it into the material.
pub(super) fn search(
    run: &Run,
    base: &[[f64; 3]],
    undistorted: &[[f64; 3]],
    sigma: &[f64],
    corners: &[CornerSpot],
    orig_periods: usize,
) -> Result<Searched, Error> {
    let n = corners.len();
    let mut theta = vec![[0.0f64; 4]; n];
    let eval = |th: &[[f64; 4]]| -> Result<(Vec<[f64; 3]>, Eval), Error> {
        let mut b = base.to_vec();
        for (c, s) in corners.iter().enumerate() {
            if stop_s(th[c][3]) > 0.0 {
                for k in 0..b.len() {
                    if (s.lo..=s.hi).contains(&sigma[k]) {
                        b[k] = undistorted[k];
                    }
                }
            }
        }
        let pts = split_points(run.start, &b, corners, th);
        let feeds = split_feeds(&run.reference, &run.base_feed, corners, th);
        let e = run.evaluate_dwelling(&pts, &feeds, &split_dwells(pts.len(), corners, th))?;
        Ok((pts, e))
    };
    let (mut pts, mut cur_eval) = eval(&theta)?;
    let mut cur = score(&run.reference, corners, &cur_eval);
    let before = cur.clone();
    let share = SEARCH_SHARE * run.time_budget;
    let budget = (share * orig_periods as f64 / n.max(1) as f64).floor() as usize;
    let mut step = vec![STEP0_MM; n];
    let mut dir = vec![0usize; n];
    let mut fails = vec![0usize; n];
    let mut active: Vec<bool> = corners.iter().map(|c| c.cap_mm > STEP_MIN_MM).collect();
    let mut refused_gouge = vec![0usize; n];
    let mut refused_time = vec![0usize; n];
    let mut simulations = 1;
    let mut last_theta = theta.clone();
    for _round in 0..MAX_ROUNDS {
        if !active.iter().any(|a| *a) {
            break;
        }
        let mut trial = theta.clone();
        for c in 0..n {
            if !active[c] {
                continue;
            }
            let cap = corners[c].cap_mm;
            let stop = if corners[c].outside {
                0.0
            } else {
                MAX_STOP_S / STOP_S_PER_MM
            };
            let bounds = [
                (0.0, cap),
                (-cap, cap),
                (0.0, corners[c].cap_lead_mm),
                (0.0, stop),
            ];
            let dirs: &[[f64; 4]] = if corners[c].outside {
                &DIRS
            } else {
                &DIRS_INSIDE
            };
            for (d, (lo, hi)) in bounds.iter().enumerate() {
                trial[c][d] = (theta[c][d] + step[c] * dirs[dir[c]][d]).clamp(*lo, *hi);
            }
        }
        let (_, e) = eval(&trial)?;
        simulations += 1;
        let sc = score(&run.reference, corners, &e);
        // Over the whole program's budget: no corner may take longer than it does now.
        let over = e.periods as f64 > (1.0 + share) * orig_periods as f64;
        let mut moved = false;
        for c in 0..n {
            if !active[c] {
                continue;
            }
            let gouge_ok = sc[c].gouge <= (0.9 * GOUGE_LIMIT_MM).max(cur[c].gouge);
            let time_ok = sc[c].periods <= before[c].periods + budget && !over;
            let better =
                sc[c].objective(&corners[c]) < cur[c].objective(&corners[c]) * (1.0 - 1e-6);
            if trial[c] != theta[c] && better && gouge_ok && time_ok {
                theta[c] = trial[c];
                fails[c] = 0;
                moved = true;
                continue;
            }
            if better && !gouge_ok {
                refused_gouge[c] += 1;
            }
            if better && gouge_ok && !time_ok {
                refused_time[c] += 1;
            }
            let dirs = if corners[c].outside {
                DIRS.len()
            } else {
                DIRS_INSIDE.len()
            };
            dir[c] = (dir[c] + 1) % dirs;
            fails[c] += 1;
            if fails[c] >= dirs {
                fails[c] = 0;
                step[c] *= 0.5;
                if step[c] < STEP_MIN_MM {
                    active[c] = false;
                }
            }
        }
        if moved {
            let (p, e) = eval(&theta)?;
            simulations += 1;
            // The moves of several corners together may exceed the program's time budget
            // where each alone did not: then they are all taken back.
            if e.periods as f64 > (1.0 + share) * orig_periods as f64 {
                theta = last_theta.clone();
                step.iter_mut().for_each(|s| *s *= 0.5);
                refused_time.iter_mut().for_each(|r| *r += 1);
                continue;
            }
            (pts, cur_eval) = (p, e);
            last_theta = theta.clone();
            cur = score(&run.reference, corners, &cur_eval);
        }
    }
    let dwells = split_dwells(pts.len(), corners, &theta);
    Ok((
        CornerResult {
            before,
            after: cur,
            refused_gouge,
            refused_time,
            simulations,
        },
        pts,
        split_feeds(&run.reference, &run.base_feed, corners, &theta),
        dwells,
        cur_eval,
    ))
}
