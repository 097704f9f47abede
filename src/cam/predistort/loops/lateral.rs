//! Stage 5 of the loop search: every point near a corner moves sideways, by norm-optimal ILC
//! steps on a smooth basis.
//!
//! Why. Stages 1–4 shape each loop with six numbers and leave the points between the loops on
//! the main iteration's correction. Where the loops fill the path (the 2 mm staircase at
//! F 3000), the loops' chords and the points between them all run at one speed, set by the
//! loops' curvature, and the error left is a swing of the tool after each loop as it settles
//! back onto the leg (10–20 µm for half a millimetre on kv 60 axes), a shape six numbers
//! cannot take out.
//!
//! Method. Around corner `c` every point `k` of the window `lo..hi` (not a kept line's, not the
//! end) moves by `δ_k = Σ_j θ_cj·B((u_k − u_j)/h)·n_k`: `u_k` the point's chord length along
//! the points, `B` the cubic B-spline (support ±2), knots `u_j` every `h` = [`KNOT_MM`] from
//! two knots inside the window's first point to two inside its last (so the offset is zero at
//! the window's ends), and `n_k` the unit normal to the points' local direction in the
//! corner's plane. The residuals are the corner-window ILC's (module `ilc`: error vectors at
//! equal steps of tool path length over the window, each times `√Δs`); their Jacobian in
//! `θ_c` is measured by finite differences, the coefficients of the even and of the odd
//! corners in one simulation each, and the step is the Levenberg–Marquardt update
//! `θ_c ← θ_c − (J_cᵀJ_c + λ·(diag J_cᵀJ_c + εI))⁻¹ J_cᵀ r_c` (norm-optimal ILC on the lifted
//! system, Amann, Owens & Rogers 1996; Marquardt 1963), all corners' steps simulated together
//! and taken when the search's objective falls (within the duration budget: the objective's
//! penalty refuses a step past it). `λ` falls threefold after a step taken and rises fourfold
//! after one refused; the Jacobian is measured again after every step taken.
//!
//! The stage runs after stage 4, within its own work bound [`WORK_PERIODS`].

use nalgebra::{DMatrix, DVector};

use crate::numeric::vec3::cross;

use super::super::Error;
use super::super::POSITION_DECIMALS;
use super::super::corners::CornerSpot;
use super::super::run::{Eval, Run, norm, round_to, sub};
use super::descent::{Best, corner_residuals};

/// Knot spacing of the offsets' B-splines along the points, mm (five loop chords).
pub const KNOT_MM: f64 = 0.1;

/// Most knots per corner window (a longer window spaces them wider).
const MAX_KNOTS: usize = 40;

/// Finite-difference step of the coefficients, mm (20 times the 0.1 µm rounding of the
/// points).
const FD_STEP_MM: f64 = 2e-3;

/// Largest change of one coefficient in one step, mm.
const MAX_MOVE_MM: f64 = 0.01;

/// Levenberg–Marquardt damping of the first step (relative to the diagonal of `JᵀJ`).
const LAMBDA0: f64 = 1e-2;

/// Most steps taken or refused.
const MAX_TRIALS: usize = 24;

/// Work bound of the stage: simulated interpolation periods, 2,000,000 (some 2,000
/// simulations of a 1 s program; a Jacobian of the staircase costs some 40).
pub const WORK_PERIODS: usize = 2_000_000;

/// Cubic B-spline of unit knot spacing centred on 0 (support `(−2, 2)`).
fn bspline(u: f64) -> f64 {
    let a = u.abs();
    if a >= 2.0 {
        0.0
    } else if a >= 1.0 {
        (2.0 - a).powi(3) / 6.0
    } else {
        (4.0 - 6.0 * a * a + 3.0 * a * a * a) / 6.0
    }
}

/// The moving points of one corner: their indices, unit normals and knot weights.
pub(super) struct Window {
    pub points: Vec<usize>,
    pub normals: Vec<[f64; 3]>,
    /// `weights[i][j]`: B-spline `j` at point `points[i]`.
    pub weights: Vec<Vec<f64>>,
    pub knots: usize,
}

/// `a / |a|`, or `None` where `|a|` is below 1e-12 (a reversal's turn has no plane).
fn unit(a: [f64; 3]) -> Option<[f64; 3]> {
    let n = norm(a);
    (n > 1e-12).then(|| a.map(|v| v / n))
}

/// The windows of `spots` over the points `pts` (path parameters `sigma`); `still(k)` marks
/// points that may not move. A corner whose turn has no plane (a reversal) or whose window
/// holds too few points gets an empty window.
pub(super) fn windows(
    pts: &[[f64; 3]],
    sigma: &[f64],
    spots: &[CornerSpot],
    still: &dyn Fn(usize) -> bool,
) -> Vec<Window> {
    let m = pts.len();
    let mut chord = vec![0.0f64; m];
    for k in 1..m {
        chord[k] = chord[k - 1] + norm(sub(pts[k], pts[k - 1]));
    }
    spots
        .iter()
        .map(|s| {
            let empty = Window {
                points: Vec::new(),
                normals: Vec::new(),
                weights: Vec::new(),
                knots: 0,
            };
            let Some(plane) = unit(cross(s.d_in, s.d_out)) else {
                return empty;
            };
            let idx: Vec<usize> = (0..m)
                .filter(|&k| sigma[k] >= s.lo && sigma[k] <= s.hi)
                .collect();
            let (Some(&first), Some(&last)) = (idx.first(), idx.last()) else {
                return empty;
            };
            let span = chord[last] - chord[first];
            let h = KNOT_MM.max(span / (MAX_KNOTS + 3) as f64);
            let knots = ((span / h).floor() as usize).saturating_sub(3);
            if knots == 0 {
                return empty;
            }
            let mut out = Window { knots, ..empty };
            for &k in idx.iter().filter(|&&k| !still(k)) {
                let a = pts[k.saturating_sub(1)];
                let b = pts[(k + 1).min(m - 1)];
                let Some(n) = unit(sub(b, a)).and_then(|t| unit(cross(plane, t))) else {
                    continue;
                };
                let u = chord[k] - chord[first];
                let w: Vec<f64> = (0..knots)
                    .map(|j| bspline((u - (j + 2) as f64 * h) / h))
                    .collect();
                out.points.push(k);
                out.normals.push(n);
                out.weights.push(w);
            }
            out
        })
        .collect()
}

/// The points `base` with every window's offsets `theta` (per corner, per knot, mm) applied.
pub(super) fn apply(base: &[[f64; 3]], wins: &[Window], theta: &[Vec<f64>]) -> Vec<[f64; 3]> {
    let mut out = base.to_vec();
    for (w, th) in wins.iter().zip(theta) {
        for ((&k, n), wt) in w.points.iter().zip(&w.normals).zip(&w.weights) {
            let off: f64 = wt.iter().zip(th).map(|(a, b)| a * b).sum();
            if off != 0.0 {
                out[k] =
                    std::array::from_fn(|d| round_to(base[k][d] + off * n[d], POSITION_DECIMALS));
            }
        }
    }
    out
}

/// Runs the stage on `best` (its arrays describe the run's points on entry), updating its
/// points, simulation and objective. `score` is the search's objective of a simulation,
/// `still(k)` marks points that may not move, `count(e)` books a simulation.
pub(super) fn lateral(
    run: &mut Run,
    best: &mut Best,
    spots: &[CornerSpot],
    score: &dyn Fn(&Run, &Eval) -> f64,
    still: &dyn Fn(usize) -> bool,
    count: &dyn Fn(&Eval),
) -> Result<(), Error> {
    best.1.install(run);
    let base = best.1.pts.clone();
    let wins = windows(&base, &best.1.sigma, spots, still);
    if wins.iter().all(|w| w.points.is_empty()) {
        return Ok(());
    }
    let n = spots.len();
    let resid = |run: &Run, e: &Eval| corner_residuals(run, spots, e);
    let work = std::cell::Cell::new(0usize);
    let sim = |run: &mut Run, pts: &[[f64; 3]]| -> Result<Eval, Error> {
        let e = run.evaluate(pts)?;
        work.set(work.get() + e.actual[0].len());
        count(&e);
        Ok(e)
    };
    let mut theta: Vec<Vec<f64>> = wins.iter().map(|w| vec![0.0; w.knots]).collect();
    let mut res = resid(run, &best.2);
    let mut lambda = LAMBDA0;
    let mut jac: Option<Vec<DMatrix<f64>>> = None;
    let most_knots = wins.iter().map(|w| w.knots).max().unwrap_or(0);
    for _ in 0..MAX_TRIALS {
        if jac.is_none() {
            if work.get() + 2 * most_knots * best.2.actual[0].len() > WORK_PERIODS {
                break;
            }
            let mut j: Vec<DMatrix<f64>> = (0..n)
                .map(|c| DMatrix::zeros(res[c].len(), wins[c].knots))
                .collect();
            for i in 0..most_knots {
                for parity in 0..2 {
                    let mut th = theta.clone();
                    let mut any = false;
                    for c in (parity..n).step_by(2) {
                        if i < wins[c].knots && !wins[c].points.is_empty() {
                            th[c][i] += FD_STEP_MM;
                            any = true;
                        }
                    }
                    if !any {
                        continue;
                    }
                    let e = sim(run, &apply(&base, &wins, &th))?;
                    let r = resid(run, &e);
                    for c in (parity..n).step_by(2) {
                        if i < wins[c].knots && !wins[c].points.is_empty() {
                            j[c].set_column(i, &((&r[c] - &res[c]) / FD_STEP_MM));
                        }
                    }
                }
            }
            jac = Some(j);
        }
        let Some(j) = jac.as_ref() else { break };
        if work.get() + best.2.actual[0].len() > WORK_PERIODS {
            break;
        }
        let trial: Vec<Vec<f64>> = (0..n)
            .map(|c| {
                let k = wins[c].knots;
                if k == 0 || wins[c].points.is_empty() {
                    return theta[c].clone();
                }
                let jtj = j[c].transpose() * &j[c];
                let g = j[c].transpose() * &res[c];
                let scale = (0..k).map(|d| jtj[(d, d)]).fold(0.0, f64::max);
                let mut a = jtj.clone();
                for d in 0..k {
                    a[(d, d)] += lambda * (jtj[(d, d)] + 1e-9 * scale + 1e-300);
                }
                let step = a.lu().solve(&(-g)).unwrap_or_else(|| DVector::zeros(k));
                (0..k)
                    .map(|d| {
                        let s = step[d];
                        theta[c][d]
                            + if s.is_finite() {
                                s.clamp(-MAX_MOVE_MM, MAX_MOVE_MM)
                            } else {
                                0.0
                            }
                    })
                    .collect()
            })
            .collect();
        let pts = apply(&base, &wins, &trial);
        let e = sim(run, &pts)?;
        let s = score(run, &e);
        if s < best.0 - 1e-9 {
            theta = trial;
            res = resid(run, &e);
            best.0 = s;
            best.1.pts = pts;
            best.2 = e;
            lambda /= 3.0;
            jac = None;
        } else {
            lambda *= 4.0;
            if lambda > 1e4 {
                break;
            }
        }
    }
    Ok(())
}
