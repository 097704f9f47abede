//! Corner-window iterative learning control (issue 24), run after the corner stage (module
//! `corners`): every G01 point near a corner the junction limit slows (the last cruise points,
//! the end of the braking `Q`, the carried-past `P_in`, the led-in `P_out` and the first points
//! of the acceleration) moves in the corner's plane, all at once, by norm-optimal ILC steps on
//! the lifted system.
//!
//! Why. The corner stage moves three points per corner by pattern search and stops in a local
//! minimum; the error it leaves lies along the braking and accelerating stretches beside the
//! corner, which only a correction of every point there can take out. The map from the points
//! to the simulated tool path goes through the jerk-limited interpolator (not linear: its
//! timing and junction speeds follow the geometry), so the learning filter is the map's own
//! Jacobian, measured by finite differences on the service's interpolation and simulation (the
//! exact servo model), rather than the servo's impulse response alone.
//!
//! Method. Corner `c`'s error is sampled on its window (the tool path whose feet lie in
//! `lo..hi`) at [`GRID`] points equally spaced in *tool path length*, each error vector scaled
//! by `√(Δs)`: the sum of squares is the trapezoidal `∫|e|² ds` of the distance-weighted RMS,
//! and sampling by path length rather than by period makes the residuals blind to the timing
//! shifts the interpolator makes when a point moves (a lag along the path is no contour error).
//! At an inside corner each sample within 1 mm of the corner adds the residual
//! `√(Δs·K)·max(0, g − ½ GOUGE_LIMIT_MM)`, `g` its offset beyond the path outside the turn.
//! With `J_c` the residuals' Jacobian in the corner's point offsets `θ_c` (two in-plane
//! directions per point), the step is the Levenberg–Marquardt (norm-optimal ILC) update
//! `θ_c ← θ_c − (J_cᵀJ_c + λ_c·(diag J_cᵀJ_c + εI))⁻¹ J_cᵀ r_c` (Amann, Owens & Rogers 1996
//! with the lifted plant `J_c`; Marquardt 1963 for `λ_c`). Jacobian columns of the even
//! and of the odd corners are measured in one simulation per column each (a point moves only
//! its own window's residuals, the nearest other window being two corners away). A corner's
//! step is tried when its objective (as the corner stage judges it: distance-weighted squared
//! error, the squared max, the gouge) falls, it keeps the tool out of the material (at an
//! inside corner within 0.9 × [`GOUGE_LIMIT_MM`] or its present offset; at an outside corner
//! no deeper into the turn than when the stage began) and within its share of
//! [`ILC_SHARE`] of the duration budget. The tried corners' steps are then simulated together (a corner's moves
//! reach into its neighbours' windows) and kept when every corner still passes those checks
//! and the objectives' sum falls (or each corner's own does); corners that fail are dropped
//! and the rest tried again, twice at most. A kept corner's `λ_c` falls threefold, the others'
//! rise fourfold. The stage stops after [`MAX_STEPS`] steps or when the next would pass its
//! work bound [`WORK_PERIODS`] of simulated periods (the simulations cost the whole program's
//! length each; the caller notes the bound). Moving `Q` moves the stretch of the block `Q → P_in`, whose feed therefore
//! follows it (the original's top speed over that stretch, as the corner stage sets it), so
//! that no block runs slower than the original did along its stretch.
//!
//! Reference: Amann, Owens & Rogers 1996 (norm-optimal ILC); Marquardt 1963.

use nalgebra::{DMatrix, DVector};

use super::corners::{self, CornerScore, CornerSpot, GOUGE_LIMIT_MM};
use super::measure::tips_of;
use super::reference::Reference;
use super::{Error, Eval, POSITION_DECIMALS, Run, norm, round_to, sub};

/// Residual samples (error vectors) per corner window.
const GRID: usize = 240;

/// Finite-difference step of the Jacobian, mm: 100 times the 0.1 µm rounding of the points,
/// a secant over the interpolator's small non-smooth responses (4 µm left the 10 mm square at
/// F3000, kv 60, at 0.33× where 7–10 µm reach 0.25×, tests_corners).
const FD_STEP_MM: f64 = 1e-2;

/// Largest move of one point coordinate in one step, mm.
const MAX_MOVE_MM: f64 = 0.01;

/// Points before `Q` and after `P_out` that move, per corner.
const SIDE_POINTS: usize = 10;

/// Farthest a moving point lies from its corner, mm.
const REACH_MM: f64 = 3.0;

/// Most ILC steps (each: the Jacobian when the step before was kept, then one to three
/// simulations of the step).
pub(super) const MAX_STEPS: usize = 14;

/// Levenberg–Marquardt damping of the first step (relative to the diagonal of `JᵀJ`).
const LAMBDA0: f64 = 1e-2;

/// Fraction of the duration budget (`max_duration_ratio − 1`) the corner stage and this
/// stage may spend together: 14/15 (0.14 of the original's duration at the default ratio
/// 1.15, leaving a margin for the rounding of the written program; the corner stage alone
/// keeps within [`super::corners::SEARCH_SHARE`]).
pub(super) const ILC_SHARE: f64 = 14.0 / 15.0;

/// Weight of the squared gouge excess against the squared error (dimensionless).
const GOUGE_K: f64 = 1e4;

/// The points of one corner that move and the two directions they move in.
struct Window {
    points: Vec<usize>,
    basis: [[f64; 3]; 2],
}

/// Most interpolation periods the stage simulates in all (its work bound): 6,000,000, room
/// for all [`MAX_STEPS`] on a program of some 5 s (every corner program of the tests, whose
/// figures it leaves as they are); on longer programs the stage takes as many steps as fit
/// (each step's Jacobian simulates the whole program some 100 times) and says so.
pub const WORK_PERIODS: usize = 6_000_000;

/// How the stage went.
pub(super) struct IlcOutcome {
    /// Simulations run.
    pub simulations: usize,
    /// Steps taken before the work bound [`WORK_PERIODS`] stopped the stage (`None`: it was
    /// not reached).
    pub bounded_after: Option<usize>,
}

/// The moving points of each corner (`Q`, `P_in`, `P_out` and up to [`SIDE_POINTS`] within
/// [`REACH_MM`] on either side, none of a neighbour's, none `fixed`, never the end) and the
/// corner's plane (`d_in` and the part of `d_out` normal to it).
fn windows(pts: &[[f64; 3]], corners: &[CornerSpot], fixed: &dyn Fn(usize) -> bool) -> Vec<Window> {
    let m = pts.len();
    let mut out: Vec<Window> = Vec::with_capacity(corners.len());
    let mut floor = 0usize;
    for (c, s) in corners.iter().enumerate() {
        let q = s.k + 2 * c;
        // The window reaches REACH_MM back from Q and on from P_out, never into the
        // neighbouring corners' windows.
        let ceiling = corners
            .get(c + 1)
            .map_or(m.saturating_sub(1), |n| n.k + 2 * (c + 1));
        let mut list = Vec::new();
        let mut j = q;
        let mut n = 0;
        while j > floor && n < SIDE_POINTS && norm(sub(pts[j - 1], pts[q])) <= REACH_MM {
            j -= 1;
            n += 1;
        }
        list.extend(j..=q + 2);
        let mut j = q + 2;
        let mut n = 0;
        while j + 1 < ceiling && n < SIDE_POINTS && norm(sub(pts[j + 1], pts[q + 2])) <= REACH_MM {
            j += 1;
            n += 1;
            list.push(j);
        }
        list.retain(|&j| j + 1 < m && !fixed(j));
        floor = list.last().copied().unwrap_or(floor).max(q + 2) + 1;
        let e1 = s.d_in;
        let dot = (0..3).map(|d| s.d_out[d] * e1[d]).sum::<f64>();
        let n2: [f64; 3] = std::array::from_fn(|d| s.d_out[d] - dot * e1[d]);
        let ln = norm(n2).max(1e-12);
        out.push(Window {
            points: list,
            basis: [e1, n2.map(|v| v / ln)],
        });
    }
    out
}

/// Residuals of corner `spot` on the simulation `e` (module docs): at each of [`GRID`] points
/// equally spaced in tool path length over the window, the error vector's three components
/// times `√Δs` (mm·√mm) and the gouge term (zero at an outside corner).
pub(super) fn residuals(
    reference: &Reference,
    spot: &CornerSpot,
    e: &Eval,
    tips: &[[f64; 3]],
) -> Vec<f64> {
    let feet = &e.feet;
    let n = feet.len();
    let mut out = Vec::with_capacity(4 * GRID);
    let Some(i0) = feet.iter().position(|(s, _)| *s >= spot.lo) else {
        out.resize(4 * GRID, 0.0);
        return out;
    };
    // The window's polyline of (tip, foot s, error), with interpolated ends.
    let lerp = |a: usize, b: usize, f: f64| -> ([f64; 3], f64, [f64; 3]) {
        let t = std::array::from_fn(|d| tips[a][d] + f * (tips[b][d] - tips[a][d]));
        let s = feet[a].0 + f * (feet[b].0 - feet[a].0);
        let v = std::array::from_fn(|d| feet[a].1[d] + f * (feet[b].1[d] - feet[a].1[d]));
        (t, s, v)
    };
    let frac = |a: usize, b: usize, x: f64| {
        let ds = feet[b].0 - feet[a].0;
        if ds.abs() > 1e-12 {
            ((x - feet[a].0) / ds).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let mut poly = Vec::new();
    if i0 > 0 {
        poly.push(lerp(i0 - 1, i0, frac(i0 - 1, i0, spot.lo)));
    }
    let mut i = i0;
    while i < n && feet[i].0 <= spot.hi {
        poly.push(lerp(i, i, 0.0));
        i += 1;
    }
    if i < n && i > 0 {
        poly.push(lerp(i - 1, i, frac(i - 1, i, spot.hi)));
    }
    let mut cum = vec![0.0f64; poly.len()];
    for k in 1..poly.len() {
        cum[k] = cum[k - 1] + norm(sub(poly[k].0, poly[k - 1].0));
    }
    let total = *cum.last().unwrap_or(&0.0);
    let ds = total / GRID as f64;
    let root = ds.sqrt();
    let mut j = 0usize;
    for g in 0..GRID {
        let target = (g as f64 + 0.5) * ds;
        while j + 2 < poly.len() && cum[j + 1] < target {
            j += 1;
        }
        let (s, v) = if poly.len() < 2 {
            poly.first().map_or((spot.sigma, [0.0; 3]), |p| (p.1, p.2))
        } else {
            let len = cum[j + 1] - cum[j];
            let f = if len > 0.0 {
                ((target - cum[j]) / len).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (a, b) = (&poly[j], &poly[j + 1]);
            (
                a.1 + f * (b.1 - a.1),
                std::array::from_fn(|d| a.2[d] + f * (b.2[d] - a.2[d])),
            )
        };
        out.extend(v.iter().map(|x| root * x));
        let gouge = if spot.outside || (s - spot.sigma).abs() > 1.0 {
            0.0
        } else {
            (corners::material_offset(reference, spot, s, v) - 0.5 * GOUGE_LIMIT_MM).max(0.0)
        };
        out.push(root * GOUGE_K.sqrt() * gouge);
    }
    out
}

/// The programmed feeds (mm/min) of the points `pts`: `feeds` with each corner's `P_in` block
/// at the original's largest speed over the stretch from `Q`'s foot to the corner (as
/// [`corners::split_feeds`] sets it for the corner stage's lead; a step that moves `Q` moves
/// the stretch, so that no block runs slower than the original did along it).
fn feeds_for(
    reference: &Reference,
    feeds: &[f64],
    corners: &[CornerSpot],
    pts: &[[f64; 3]],
) -> Vec<f64> {
    let theta: Vec<[f64; 4]> = corners
        .iter()
        .enumerate()
        .map(|(c, s)| {
            let at = reference.cum.partition_point(|v| *v < s.sigma);
            let corner = reference.knots[at.min(reference.knots.len() - 1)];
            let q = pts[s.k + 2 * c];
            let lead = (0..3).map(|d| (corner[d] - q[d]) * s.d_in[d]).sum::<f64>();
            [0.0, 0.0, lead.max(0.0), 0.0]
        })
        .collect();
    corners::split_feeds(reference, feeds, corners, &theta)
}

fn moved(p: [f64; 3], basis: &[[f64; 3]; 2], a: f64, b: f64) -> [f64; 3] {
    std::array::from_fn(|d| round_to(p[d] + a * basis[0][d] + b * basis[1][d], POSITION_DECIMALS))
}

/// Refines the corner stage's points `pts` (programmed feeds `feeds`, mm/min, as
/// [`Run::evaluate_with`] takes them; `cur` their simulation) by corner-window ILC steps
/// (module docs). `before` are the corner scores with all corner-stage offsets zero (the time
/// shares are counted from them); `fixed(j)` marks points that may not move.
/// Returns the points, their simulation and what the stage did.
pub(super) fn refine(
    run: &Run,
    pts: Vec<[f64; 3]>,
    feeds: &[f64],
    cur: Eval,
    corners: &[CornerSpot],
    before: &[CornerScore],
    fixed: &dyn Fn(usize) -> bool,
) -> Result<(Vec<[f64; 3]>, Eval, IlcOutcome), Error> {
    let n = corners.len();
    let mut outcome = IlcOutcome {
        simulations: 0,
        bounded_after: None,
    };
    if n == 0 {
        return Ok((pts, cur, outcome));
    }
    let win = windows(&pts, corners, fixed);
    let orig = run.orig_periods as f64;
    let tb = ILC_SHARE * run.time_budget;
    let budget = (tb * orig / n as f64).floor() as usize;
    let mut pts = pts;
    let mut cur = cur;
    let mut score = corners::score(&run.reference, corners, &cur);
    let mut lambda = vec![LAMBDA0; n];
    let start_gouge: Vec<f64> = score.iter().map(|s| s.gouge).collect();
    let all_res = |e: &Eval| -> Vec<Vec<f64>> {
        let tips = tips_of(&e.actual);
        corners
            .iter()
            .map(|s| residuals(&run.reference, s, e, &tips))
            .collect()
    };
    let mut res = all_res(&cur);
    let fd = FD_STEP_MM;
    let mm = MAX_MOVE_MM;
    let mut jac: Vec<Option<DMatrix<f64>>> = vec![None; n];
    let mut stale = true;
    // Periods one simulation costs (the run is padded to at least the original's length).
    let per_sim = cur.actual.first().map_or(1, Vec::len).max(1);
    let jacobian_sims = 2 * win.iter().map(|w| 2 * w.points.len()).max().unwrap_or(0);
    for step in 0..MAX_STEPS {
        // A step: the Jacobian when it is stale, then up to three simulations of the step.
        let next = if stale { jacobian_sims + 3 } else { 3 };
        if (outcome.simulations + next) * per_sim > WORK_PERIODS {
            outcome.bounded_after = Some(step);
            break;
        }
        if stale {
            for (c, w) in win.iter().enumerate() {
                jac[c] = Some(DMatrix::zeros(res[c].len(), 2 * w.points.len()));
            }
            let most = win.iter().map(|w| 2 * w.points.len()).max().unwrap_or(0);
            for parity in 0..2 {
                for v in 0..most {
                    let mut trial = pts.clone();
                    let mut any = false;
                    for (c, w) in win.iter().enumerate() {
                        if c % 2 != parity || v >= 2 * w.points.len() {
                            continue;
                        }
                        let j = w.points[v / 2];
                        let (a, b) = if v % 2 == 0 { (fd, 0.0) } else { (0.0, fd) };
                        trial[j] = moved(pts[j], &w.basis, a, b);
                        any = true;
                    }
                    if !any {
                        continue;
                    }
                    let e = run.evaluate_with(
                        &trial,
                        &feeds_for(&run.reference, feeds, corners, &trial),
                    )?;
                    outcome.simulations += 1;
                    let tips = tips_of(&e.actual);
                    for (c, w) in win.iter().enumerate() {
                        if c % 2 != parity || v >= 2 * w.points.len() {
                            continue;
                        }
                        let r = residuals(&run.reference, &corners[c], &e, &tips);
                        if let Some(jc) = jac[c].as_mut() {
                            for (i, (ri, r0)) in r.iter().zip(&res[c]).enumerate() {
                                jc[(i, v)] = (ri - r0) / fd;
                            }
                        }
                    }
                }
            }
            stale = false;
        }
        // One Levenberg–Marquardt step per corner.
        let mut trial = pts.clone();
        let mut tried = vec![false; n];
        for (c, w) in win.iter().enumerate() {
            let Some(jc) = jac[c].as_ref() else { continue };
            if jc.ncols() == 0 {
                continue;
            }
            let a = jc.transpose() * jc;
            let g = jc.transpose() * DVector::from_column_slice(&res[c]);
            let eps = 1e-9 * a.trace().max(1e-300) / a.nrows() as f64;
            let mut lhs = a.clone();
            for i in 0..a.nrows() {
                lhs[(i, i)] += lambda[c] * (a[(i, i)] + eps) + eps;
            }
            let Some(ch) = lhs.cholesky() else { continue };
            let delta = ch.solve(&g);
            for (i, &j) in w.points.iter().enumerate() {
                let da = (-delta[2 * i]).clamp(-mm, mm);
                let db = (-delta[2 * i + 1]).clamp(-mm, mm);
                trial[j] = moved(pts[j], &w.basis, da, db);
            }
            tried[c] = w.points.iter().any(|&j| trial[j] != pts[j]);
        }
        if !tried.iter().any(|t| *t) {
            break;
        }
        let e = run.evaluate_with(&trial, &feeds_for(&run.reference, feeds, corners, &trial))?;
        outcome.simulations += 1;
        let sc = corners::score(&run.reference, corners, &e);
        let over = e.periods as f64 > (1.0 + tb) * orig;
        let mut keep = vec![false; n];
        for c in 0..n {
            if !tried[c] {
                continue;
            }
            let held = if corners[c].outside {
                start_gouge[c]
            } else {
                score[c].gouge
            };
            let gouge_ok = sc[c].gouge <= (0.9 * GOUGE_LIMIT_MM).max(held);
            let time_ok = sc[c].periods <= before[c].periods + budget && !over;
            let better =
                sc[c].objective(&corners[c]) < score[c].objective(&corners[c]) * (1.0 - 1e-4);
            keep[c] = better && gouge_ok && time_ok;
        }
        if !keep.iter().any(|k| *k) {
            lambda.iter_mut().for_each(|l| *l *= 4.0);
            if lambda.iter().all(|l| *l > 1e4) {
                break;
            }
            continue;
        }
        // Moves of several corners together may interact (a corner's timing and its points
        // reach into the next one's window): the merged points must pass every corner's
        // checks again; corners that fail them (or whose neighbours fail) are dropped, twice
        // at most, before the whole step is taken back.
        let mut first = Some(e);
        let mut merged = None;
        for _try in 0..3 {
            if !keep.iter().any(|k| *k) {
                break;
            }
            let mut next = pts.clone();
            for (c, w) in win.iter().enumerate() {
                if keep[c] {
                    for &j in &w.points {
                        next[j] = trial[j];
                    }
                }
            }
            let e = match first.take() {
                Some(e) if keep.iter().zip(&tried).all(|(k, t)| k == t) => e,
                _ => {
                    outcome.simulations += 1;
                    run.evaluate_with(&next, &feeds_for(&run.reference, feeds, corners, &next))?
                }
            };
            let sc = corners::score(&run.reference, corners, &e);
            if e.periods as f64 > (1.0 + tb) * orig {
                break;
            }
            let total =
                |s: &[CornerScore]| -> f64 { (0..n).map(|c| s[c].objective(&corners[c])).sum() };
            let lower = total(&sc) < total(&score) * (1.0 - 1e-4);
            let failing: Vec<usize> = (0..n)
                .filter(|&c| {
                    let held = if corners[c].outside {
                        start_gouge[c]
                    } else {
                        score[c].gouge
                    };
                    let old = score[c].objective(&corners[c]);
                    let new = sc[c].objective(&corners[c]);
                    let better = if keep[c] {
                        new < old
                    } else {
                        new <= old * 1.02
                    };
                    !(sc[c].gouge <= (0.9 * GOUGE_LIMIT_MM).max(held)
                        && sc[c].periods <= before[c].periods + budget
                        && (lower || better))
                })
                .collect();
            if failing.is_empty() {
                merged = Some((next, e));
                break;
            }
            for &c in &failing {
                if keep[c] {
                    keep[c] = false;
                } else {
                    for d in [c.wrapping_sub(1), c + 1] {
                        if d < n {
                            keep[d] = false;
                        }
                    }
                }
            }
        }
        let Some((next, e)) = merged else {
            lambda.iter_mut().for_each(|l| *l *= 4.0);
            continue;
        };
        for c in 0..n {
            if keep[c] {
                lambda[c] = (lambda[c] / 3.0).max(1e-6);
            } else {
                lambda[c] *= 4.0;
            }
        }
        pts = next;
        cur = e;
        score = corners::score(&run.reference, corners, &cur);
        res = all_res(&cur);
        stale = true;
    }
    Ok((pts, cur, outcome))
}

#[cfg(test)]
mod tests;
