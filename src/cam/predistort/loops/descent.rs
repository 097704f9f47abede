//! Stages 2 and 3 of the loop search: each corner's own six numbers, from a shared shape.
//!
//! Stage 2 is a pattern search: one of the six numbers moves at every corner at once, and
//! each corner keeps the move where its own window's objective fell (the windows are apart:
//! one simulation judges all corners), if the program's objective falls too; the step halves
//! when no move helps, and the search starts again from the largest step (at most twice)
//! while a round still improves.
//!
//! Stage 3. The pattern search of stage 2 moves one of the six numbers at a time and stops where no
//! single move helps, though a move of several together still would. This stage measures,
//! per corner, the Jacobian of the corner's residuals (its error vectors sampled at equal
//! steps of tool path length over its window, each times `√Δs`, as the corner-window ILC
//! samples them: module `ilc`) in its six numbers by finite differences, and takes the
//! Levenberg–Marquardt step `θ_c ← θ_c − (J_cᵀJ_c + λ_c·(diag J_cᵀJ_c + εI))⁻¹ J_cᵀ r_c`
//! (Marquardt 1963), the norm-optimal ILC update on the six numbers (Amann, Owens & Rogers
//! 1996). The columns of the even and of the odd corners are measured in one simulation each
//! (a loop moves its own window's error; the next window of the same parity is two corners
//! away), 12 simulations per Jacobian. A step is judged as stage 2 judges a move: each corner
//! keeps its step where its window's objective fell, and the steps kept are simulated
//! together and taken when the program's objective falls; `λ_c` falls threefold where a
//! corner's step was taken and rises fourfold elsewhere.

use nalgebra::{DMatrix, DVector};

use super::super::Error;
use super::super::corners::CornerSpot;
use super::super::ilc::residuals;
use super::super::measure::tips_of;
use super::super::run::{Eval, Run};
use super::Arrays;

/// The best candidate so far: objective, arrays, simulation, the six numbers per corner.
pub(super) type Best = (f64, Arrays, Eval, Vec<[f64; 6]>);

/// A candidate's objective, arrays and simulation (`None`: the work bound is spent).
pub(super) type Tried = Option<(f64, Arrays, Eval)>;

/// A candidate's simulation and objective from its six numbers per corner.
pub(super) type EvalFn<'a> = dyn Fn(&mut Run, &[[f64; 6]]) -> Result<Tried, Error> + 'a;

/// A corner's six numbers within their room, against the neighbours' numbers given.
pub(super) type ClampFn<'a> = dyn Fn(usize, [f64; 6], &[[f64; 6]]) -> [f64; 6] + 'a;

/// Most steps of the stage.
const MAX_STEPS: usize = 24;

/// Finite-difference step of the Jacobian, mm (as the corner-window ILC's: a secant over the
/// interpolator's small non-smooth responses).
const FD_STEP_MM: f64 = 1e-2;

/// Largest change of one number in one step, in units of the corner's lag length.
const MAX_MOVE_LAGS: f64 = 0.1;

/// Levenberg–Marquardt damping of the first step (relative to the diagonal of `JᵀJ`).
const LAMBDA0: f64 = 1e-2;

/// The stage's inputs that stay fixed: the corners, their lag lengths (mm), and the search's
/// closures (`eval`: a candidate's simulation and objective; `clamp`: a corner's numbers
/// within their room, against the neighbours' numbers given; `window`: each corner's
/// window objective).
pub(super) struct Stage<'a> {
    pub spots: &'a [CornerSpot],
    pub lag: &'a [f64],
    pub eval: &'a EvalFn<'a>,
    pub clamp: &'a ClampFn<'a>,
    pub window: &'a dyn Fn(&Run, &Eval) -> Vec<f64>,
}

impl Stage<'_> {
    /// Each corner's residuals on the simulation `e`.
    fn residuals(&self, run: &Run, e: &Eval) -> Vec<DVector<f64>> {
        corner_residuals(run, self.spots, e)
    }

    /// `wanted` clamped corner by corner in path order, each against the corners before it
    /// as clamped and the ones after it as in `best` (so that two neighbours growing
    /// towards each other stay within their shared room).
    fn clamped(&self, wanted: &[[f64; 6]], best: &[[f64; 6]]) -> Vec<[f64; 6]> {
        let mut out = best.to_vec();
        for (c, w) in wanted.iter().enumerate() {
            out[c] = (self.clamp)(c, *w, &out);
        }
        out
    }

    /// Stages 2 and 3 from `start`: the best candidate found.
    pub(super) fn descend(&self, run: &mut Run, start: Best) -> Result<Best, Error> {
        let mut best = start;
        let mut scores = (self.window)(run, &best.2);
        if self.pattern(run, &mut best, &mut scores)? {
            self.refine(run, &mut best, &mut scores)?;
        }
        Ok(best)
    }

    /// Stage 2 from `best` (with `scores` its windows' objectives), updating both; `false`
    /// when the work bound stopped it.
    fn pattern(
        &self,
        run: &mut Run,
        best: &mut Best,
        scores: &mut Vec<f64>,
    ) -> Result<bool, Error> {
        let n = self.spots.len();
        let min_lag = self.lag.iter().copied().fold(f64::INFINITY, f64::min);
        let mut rounds = 0;
        let mut round_start = best.0;
        let mut step = 0.05 * min_lag;
        loop {
            if step <= 0.003 * min_lag {
                rounds += 1;
                if rounds >= 3 || best.0 >= round_start - 1e-9 {
                    return Ok(true);
                }
                round_start = best.0;
                step = 0.05 * min_lag;
            }
            let mut improved = false;
            for i in 0..6 {
                for sgn in [1.0, -1.0] {
                    let trial: Vec<[f64; 6]> = (0..n)
                        .map(|c| {
                            let mut p = best.3[c];
                            p[i] += sgn * step;
                            (self.clamp)(c, p, &best.3)
                        })
                        .collect();
                    let Some((s_t, cand_t, e_t)) = (self.eval)(run, &trial)? else {
                        return Ok(false);
                    };
                    let sc_t = (self.window)(run, &e_t);
                    let take: Vec<bool> = (0..n)
                        .map(|c| trial[c] != best.3[c] && sc_t[c] < scores[c] * (1.0 - 1e-6))
                        .collect();
                    if !take.iter().any(|&t| t) {
                        continue;
                    }
                    let (s_c, cand_c, e_c, params) = if take.iter().all(|&t| t) {
                        (s_t, cand_t, e_t, trial)
                    } else {
                        let params: Vec<[f64; 6]> = (0..n)
                            .map(|c| if take[c] { trial[c] } else { best.3[c] })
                            .collect();
                        let Some((s, cand, e)) = (self.eval)(run, &params)? else {
                            return Ok(false);
                        };
                        (s, cand, e, params)
                    };
                    if s_c < best.0 - 1e-9 {
                        *scores = (self.window)(run, &e_c);
                        *best = (s_c, cand_c, e_c, params);
                        improved = true;
                    }
                }
            }
            if !improved {
                step *= 0.5;
            }
        }
    }

    /// Stage 3 from `best` (with `scores` its windows' objectives), updating both.
    fn refine(&self, run: &mut Run, best: &mut Best, scores: &mut Vec<f64>) -> Result<(), Error> {
        let n = self.spots.len();
        let mut res = self.residuals(run, &best.2);
        let mut lambda = vec![LAMBDA0; n];
        let mut jac: Option<Vec<DMatrix<f64>>> = None;
        for _ in 0..MAX_STEPS {
            if jac.is_none() {
                let mut j: Vec<DMatrix<f64>> =
                    res.iter().map(|r| DMatrix::zeros(r.len(), 6)).collect();
                for i in 0..6 {
                    for parity in 0..2 {
                        let mut delta = vec![0.0; n];
                        let mut wanted = best.3.clone();
                        for c in (parity..n).step_by(2) {
                            let p = best.3[c];
                            let mut q = p;
                            q[i] += FD_STEP_MM;
                            let mut q = (self.clamp)(c, q, &best.3);
                            if (q[i] - p[i]).abs() < 0.5 * FD_STEP_MM {
                                q = p;
                                q[i] -= FD_STEP_MM;
                                q = (self.clamp)(c, q, &best.3);
                            }
                            delta[c] = q[i] - p[i];
                            wanted[c] = q;
                        }
                        let Some((_, _, e)) = (self.eval)(run, &wanted)? else {
                            return Ok(());
                        };
                        let r = self.residuals(run, &e);
                        for c in (parity..n).step_by(2) {
                            if delta[c] != 0.0 {
                                let col = (&r[c] - &res[c]) / delta[c];
                                j[c].set_column(i, &col);
                            }
                        }
                    }
                }
                jac = Some(j);
            }
            let Some(j) = jac.as_ref() else { break };
            let wanted: Vec<[f64; 6]> = (0..n)
                .map(|c| {
                    let jtj = j[c].transpose() * &j[c];
                    let g = j[c].transpose() * &res[c];
                    let mut a = jtj.clone();
                    let scale = (0..6).map(|d| jtj[(d, d)]).fold(0.0, f64::max);
                    for d in 0..6 {
                        a[(d, d)] += lambda[c] * (jtj[(d, d)] + 1e-9 * scale + 1e-300);
                    }
                    let step = a.lu().solve(&(-g)).unwrap_or_else(|| DVector::zeros(6));
                    let most = MAX_MOVE_LAGS * self.lag[c];
                    let mut q = best.3[c];
                    for d in 0..6 {
                        let s = step[d];
                        q[d] += if s.is_finite() {
                            s.clamp(-most, most)
                        } else {
                            0.0
                        };
                    }
                    q
                })
                .collect();
            let trial = self.clamped(&wanted, &best.3);
            let Some((s_t, cand_t, e_t)) = (self.eval)(run, &trial)? else {
                break;
            };
            let sc_t = (self.window)(run, &e_t);
            let take: Vec<bool> = (0..n)
                .map(|c| trial[c] != best.3[c] && sc_t[c] < scores[c] * (1.0 - 1e-6))
                .collect();
            let mut taken = None;
            if take.iter().any(|&t| t) {
                let (s_c, cand_c, e_c, params) = if take.iter().all(|&t| t) {
                    (s_t, cand_t, e_t, trial)
                } else {
                    let mixed: Vec<[f64; 6]> = (0..n)
                        .map(|c| if take[c] { trial[c] } else { best.3[c] })
                        .collect();
                    let params = self.clamped(&mixed, &best.3);
                    let Some((s, cand, e)) = (self.eval)(run, &params)? else {
                        break;
                    };
                    (s, cand, e, params)
                };
                if s_c < best.0 - 1e-9 {
                    taken = Some((s_c, cand_c, e_c, params));
                }
            }
            match taken {
                Some(t) => {
                    for c in 0..n {
                        lambda[c] *= if take[c] { 1.0 / 3.0 } else { 4.0 };
                    }
                    *best = t;
                    *scores = (self.window)(run, &best.2);
                    res = self.residuals(run, &best.2);
                    jac = None;
                }
                None => {
                    for l in &mut lambda {
                        *l *= 4.0;
                    }
                    if lambda.iter().all(|&l| l > 1e6) {
                        break;
                    }
                }
            }
        }
        Ok(())
    }
}

/// Each corner's residuals (module `ilc`: error vectors at equal steps of tool path length
/// over its window, each times `√Δs`) on the simulation `e`.
pub(super) fn corner_residuals(run: &Run, spots: &[CornerSpot], e: &Eval) -> Vec<DVector<f64>> {
    let tips = tips_of(&e.actual);
    spots
        .iter()
        .map(|s| DVector::from_vec(residuals(&run.reference, s, e, &tips)))
        .collect()
}
