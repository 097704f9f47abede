//! Effects added one after another (CONTRACT v1.1 "steps"): forward selection by blocked
//! cross-validation, each candidate fitted jointly with the effects already chosen.
//!
//! Effects combine additively on the stored simulation: with `Δ_e = sim_e − sim` (the
//! effect's re-simulation or correction minus the stored simulation), a set `S` predicts
//! `sim + Σ_{e∈S} Δ_e`. A candidate is fitted to `meas − Σ_{others} Δ`, and every member is
//! then refitted once to what the others leave (one backfitting sweep; two on all the data).
//! Reference: Hastie & Tibshirani, "Generalized Additive Models" (1990), backfitting.
//! Bad cases: two effects that interact strongly (friction inside a backlash gap) are only
//! approximately additive.
#![allow(clippy::needless_range_loop)] // index loops over parallel per-axis arrays read clearer

use crate::gap::effects::{Effect, Fitted};
use crate::gap::fit::{FitData, SimCache, fit, sse};
use crate::gap::plant::AxisPlant;

/// What every fit of one diagnosis shares.
pub struct Problem<'a> {
    /// One plant per axis.
    pub plants: &'a [AxisPlant],
    /// Command per axis, mm.
    pub cmd: &'a [Vec<f64>],
    /// Measured positions per axis, mm.
    pub meas: &'a [Vec<f64>],
    /// Stored simulation per axis, mm.
    pub base: &'a [Vec<f64>],
    /// Re-simulations shared by every fit.
    pub cache: &'a SimCache,
}

/// A set of effects fitted together, with each member's `Δ` per axis (mm).
#[derive(Clone, Debug, Default)]
pub struct Model {
    /// The members, in the order they were added.
    pub members: Vec<Fitted>,
    /// `Δ` of each member, per axis.
    pub deltas: Vec<Vec<Vec<f64>>>,
}

/// `Δ` of one fitted effect: its prediction minus the stored simulation, per axis (mm).
pub fn delta(
    f: &Fitted,
    plants: &[AxisPlant],
    cmd: &[Vec<f64>],
    base: &[Vec<f64>],
) -> Vec<Vec<f64>> {
    f.predict(plants, cmd, base)
        .into_iter()
        .zip(base)
        .map(|(p, b)| p.iter().zip(b).map(|(p, b)| p - b).collect())
        .collect()
}

/// The prediction of a set of effects: `base + Σ Δ` per axis (mm), see the module notes.
pub fn compose(
    members: &[Fitted],
    plants: &[AxisPlant],
    cmd: &[Vec<f64>],
    base: &[Vec<f64>],
) -> Vec<Vec<f64>> {
    let mut out = base.to_vec();
    for m in members {
        for (o, d) in out.iter_mut().zip(delta(m, plants, cmd, base)) {
            o.iter_mut().zip(d).for_each(|(o, d)| *o += d);
        }
    }
    out
}

impl Model {
    /// `Σ Δ` of the members except `skip`, per axis.
    fn sum_except(&self, skip: Option<usize>, dims: usize, n: usize) -> Vec<Vec<f64>> {
        let mut s = vec![vec![0.0; n]; dims];
        for (j, d) in self.deltas.iter().enumerate() {
            if Some(j) == skip {
                continue;
            }
            for k in 0..dims {
                s[k].iter_mut().zip(&d[k]).for_each(|(s, d)| *s += d);
            }
        }
        s
    }

    /// The prediction `base + Σ Δ`, per axis (mm).
    pub fn predict(&self, base: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let n = base.first().map_or(0, Vec::len);
        let s = self.sum_except(None, base.len(), n);
        base.iter()
            .zip(s)
            .map(|(b, s)| b.iter().zip(s).map(|(b, s)| b + s).collect())
            .collect()
    }

    /// Weighted `Σ_k Σ_i wᵢ (meas − prediction)²` (mm²).
    pub fn sse(&self, p: &Problem, w: &[f64]) -> f64 {
        let pred = self.predict(p.base);
        (0..p.meas.len())
            .map(|k| sse(&p.meas[k], &pred[k], w))
            .sum()
    }

    /// Fits member or candidate `effect` on weights `w` to what the members other than
    /// `skip` leave: `meas − Σ_{j≠skip} Δ_j`.
    fn fit_leaving(&self, p: &Problem, effect: Effect, skip: Option<usize>, w: &[f64]) -> Fitted {
        crate::numeric::stop::check();
        let n = p.meas.first().map_or(0, Vec::len);
        let others = self.sum_except(skip, p.meas.len(), n);
        let target: Vec<Vec<f64>> = p
            .meas
            .iter()
            .zip(&others)
            .map(|(m, o)| m.iter().zip(o).map(|(m, o)| m - o).collect())
            .collect();
        let data = FitData {
            plants: p.plants,
            cmd: p.cmd,
            meas: &target,
            base: p.base,
            cache: p.cache,
        };
        fit(effect, &data, w)
    }

    /// This model plus `effect`, fitted jointly on weights `w`: the newcomer to what the
    /// members leave, then `sweeps` backfitting sweeps over all members (newcomer last).
    pub fn with(&self, p: &Problem, effect: Effect, w: &[f64], sweeps: usize) -> Model {
        let mut m = self.clone();
        let f = m.fit_leaving(p, effect, None, w);
        m.deltas.push(delta(&f, p.plants, p.cmd, p.base));
        m.members.push(f);
        let last = m.members.len() - 1;
        for sweep in 0..sweeps {
            for j in 0..m.members.len() {
                // the newcomer was just fitted to the others: skip it on the first sweep
                if m.members.len() == 1 || (sweep == 0 && j == last) {
                    continue;
                }
                let f = m.fit_leaving(p, m.members[j].effect(), Some(j), w);
                m.deltas[j] = delta(&f, p.plants, p.cmd, p.base);
                m.members[j] = f;
            }
        }
        m
    }
}

/// The held-out evaluation of adding `effect` to the per-fold models `folds` (one per fold,
/// each fitted on the other folds): the new per-fold models, `Σ_j SSE_new` and `Σ_j SSE_old`
/// over the held-out samples (mm²).
pub fn cross_validate(p: &Problem, folds: &[Model], effect: Effect) -> (Vec<Model>, f64, f64) {
    let n = p.meas.first().map_or(0, Vec::len);
    cross_validate_observed(p, folds, effect, &vec![1.0; n])
}

/// [`cross_validate`] on the samples with `observed` weight 1 only (a log on the program's
/// grid, `crate::gap::align`): each fold trains and tests on its observed samples.
pub fn cross_validate_observed(
    p: &Problem,
    folds: &[Model],
    effect: Effect,
    observed: &[f64],
) -> (Vec<Model>, f64, f64) {
    let n = p.meas.first().map_or(0, Vec::len);
    let nf = folds.len();
    let fold_of = |i: usize| i * nf / n;
    let (mut held_new, mut held_old) = (0.0, 0.0);
    let mut out = Vec::with_capacity(nf);
    for (j, model) in folds.iter().enumerate() {
        let train: Vec<f64> = (0..n)
            .map(|i| if fold_of(i) == j { 0.0 } else { observed[i] })
            .collect();
        let test: Vec<f64> = (0..n)
            .map(|i| if fold_of(i) == j { observed[i] } else { 0.0 })
            .collect();
        let new = model.with(p, effect, &train, 1);
        held_new += new.sse(p, &test);
        held_old += model.sse(p, &test);
        out.push(new);
    }
    (out, held_new, held_old)
}

#[cfg(test)]
mod tests;
