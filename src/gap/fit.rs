//! Least-squares fitting of each effect's few parameters by re-simulation, on a weighted subset
//! of the samples (weights 0/1 select the training folds of blocked cross-validation).
//!
//! Written here (no crate): every effect decouples per axis into 1-D searches or 2×2 linear
//! least squares (the line search is `numeric::brent::minimize_on_grid`).
#![allow(clippy::needless_range_loop)] // index loops over parallel per-sample arrays read clearer

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

pub use crate::gap::bounds::{SearchBounds, at_bound, at_bound_of, friction_max};
use crate::gap::effects::{Effect, Fitted, cyclic_phase, first_direction, thermal_basis};
use crate::gap::plant::AxisPlant;
use crate::numeric::brent::minimize_on_grid;

/// What a fit sees: the plant, one block's command, measurement and stored simulation.
pub struct FitData<'a> {
    /// One plant per axis.
    pub plants: &'a [AxisPlant],
    /// Command per axis, mm.
    pub cmd: &'a [Vec<f64>],
    /// Measured positions per axis, mm.
    pub meas: &'a [Vec<f64>],
    /// Stored simulation per axis, mm.
    pub base: &'a [Vec<f64>],
    /// Re-simulations already run, keyed by (effect tag, axis, parameter bits): the grid stage
    /// of the 1-D searches is the same for every cross-validation fold and every step (the
    /// simulations depend on the command only, not on `meas`).
    pub cache: &'a SimCache,
}

/// Memo of re-simulations shared by the folds of one diagnosis.
#[derive(Default)]
pub struct SimCache(Mutex<HashMap<SimKey, Arc<Vec<f64>>>>);

/// (effect tag, axis, parameter bits).
type SimKey = (u8, usize, u64);

impl SimCache {
    /// The cached simulation for `key`, computing it with `sim` on a miss.
    pub fn get(&self, key: (u8, usize, f64), sim: impl FnOnce() -> Vec<f64>) -> Arc<Vec<f64>> {
        let k = (key.0, key.1, key.2.to_bits());
        if let Some(hit) = self.0.lock().expect("cache lock").get(&k) {
            return hit.clone();
        }
        let value = Arc::new(sim());
        self.0.lock().expect("cache lock").insert(k, value.clone());
        value
    }
}

/// Weighted sum of squared differences `Σ wᵢ (mᵢ − pᵢ)²` (mm²); NaN predictions count as +∞.
pub fn sse(meas: &[f64], pred: &[f64], w: &[f64]) -> f64 {
    let s: f64 = meas
        .iter()
        .zip(pred)
        .zip(w)
        .map(|((m, p), w)| w * (m - p) * (m - p))
        .sum();
    if s.is_nan() { f64::INFINITY } else { s }
}

/// `Σ wᵢ (measᵢ − play(motor)ᵢ)²` without materialising the play output (see
/// [`crate::gap::plant::play`]).
fn play_sse(motor: &[f64], meas: &[f64], b: f64, c0: f64, w: &[f64]) -> f64 {
    let half = 0.5 * b.max(0.0);
    let Some(&m0) = motor.first() else { return 0.0 };
    let mut table = m0 + c0.clamp(-half, half);
    let mut acc = 0.0;
    for ((&m, &y), &wi) in motor.iter().zip(meas).zip(w) {
        table = table.clamp(m - half, m + half);
        acc += wi * (y - table) * (y - table);
    }
    acc
}

fn quadratic_grid(max: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| max * (i as f64 / (n - 1) as f64).powi(2))
        .collect()
}

/// Fits `effect` on the samples with weight 1 in `w` (full re-simulation, loss on the subset)
/// within [`SearchBounds::FIRST`]; a fit that ends at one of those bounds is refitted once
/// within [`SearchBounds::WIDE`] (the bounds stop a runaway search, they do not judge).
/// Only the weighted samples decide: a choice they cannot make (the backlash start when they
/// do not see the gap close first) falls to a fixed default, never to a fit that saw more.
pub fn fit(effect: Effect, data: &FitData, w: &[f64]) -> Fitted {
    let first = fit_within(effect, data, w, &SearchBounds::FIRST);
    let n = w.len();
    let period = data.plants.first().map_or(0.0, |p| p.period_s);
    let duration = (n.max(2) - 1) as f64 * period;
    if at_bound_of(&first, &[], data.plants, duration, &SearchBounds::FIRST).is_empty() {
        first
    } else {
        fit_within(effect, data, w, &SearchBounds::WIDE)
    }
}

/// [`fit`] within the search bounds `bounds`.
pub fn fit_within(effect: Effect, data: &FitData, w: &[f64], bounds: &SearchBounds) -> Fitted {
    crate::numeric::stop::check();
    let axes = data.plants.len();
    match effect {
        Effect::None | Effect::Unexplained => Fitted::None,
        Effect::CoulombFriction => {
            let f = (0..axes)
                .map(|k| {
                    let p = &data.plants[k];
                    let grid = quadratic_grid(bounds.friction_factor * friction_max(p), 14);
                    let loss = |f: f64| {
                        if grid.contains(&f) {
                            let sim = data
                                .cache
                                .get((1, k, f), || p.with_friction(f, &data.cmd[k]));
                            sse(&data.meas[k], &sim, w)
                        } else {
                            sse(&data.meas[k], &p.with_friction(f, &data.cmd[k]), w)
                        }
                    };
                    minimize_on_grid(loss, &grid, 14, 1e-2).0
                })
                .collect();
            Fitted::CoulombFriction { f }
        }
        Effect::Backlash => {
            let mut bs = Vec::new();
            let mut starts = Vec::new();
            for k in 0..axes {
                crate::numeric::stop::check();
                let dir = first_direction(&data.base[k]);
                // the start in the gap only shows before the gap first closes; when the
                // training samples cannot tell (exact ties), "centred" (0) stays
                let best_start = |b: f64| -> (f64, f64) {
                    let loss =
                        |st: f64| play_sse(&data.base[k], &data.meas[k], b, st * 0.5 * b * dir, w);
                    let mut best = (0.0, loss(0.0));
                    for st in [-1.0, 1.0] {
                        let l = loss(st);
                        if l < best.1 * (1.0 - 1e-12) {
                            best = (st, l);
                        }
                    }
                    best
                };
                let (b, _) = minimize_on_grid(
                    |b| best_start(b).1,
                    &quadratic_grid(bounds.backlash_max_mm, 16),
                    16,
                    1e-2,
                );
                starts.push(best_start(b).0);
                bs.push(b);
            }
            Fitted::Backlash {
                b: bs,
                start: starts,
            }
        }
        Effect::ServoGainMismatch => {
            let kv = (0..axes)
                .map(|k| {
                    let p = &data.plants[k];
                    let (lo, hi) = bounds.kv_ratio;
                    let grid: Vec<f64> = (0..13)
                        .map(|i| p.servo.kv * lo * (hi / lo).powf(i as f64 / 12.0))
                        .collect();
                    let loss = |kv: f64| {
                        if grid.contains(&kv) {
                            let sim = data.cache.get((3, k, kv), || p.with_kv(kv, &data.cmd[k]));
                            sse(&data.meas[k], &sim, w)
                        } else {
                            sse(&data.meas[k], &p.with_kv(kv, &data.cmd[k]), w)
                        }
                    };
                    minimize_on_grid(loss, &grid, 16, 1e-2).0
                })
                .collect();
            Fitted::ServoGainMismatch { kv }
        }
        Effect::AxisSquareness => {
            let mut best = (f64::NEG_INFINITY, Fitted::None);
            for target in 0..axes {
                for source in 0..axes {
                    if target == source {
                        continue;
                    }
                    let (mut rs, mut ss) = (0.0, 0.0);
                    for i in 0..w.len() {
                        let r = data.meas[target][i] - data.base[target][i];
                        let s = data.base[source][i];
                        rs += w[i] * r * s;
                        ss += w[i] * s * s;
                    }
                    if ss > 0.0 && rs * rs / ss > best.0 {
                        best = (
                            rs * rs / ss,
                            Fitted::AxisSquareness {
                                target,
                                source,
                                alpha: rs / ss,
                            },
                        );
                    }
                }
            }
            best.1
        }
        Effect::ScaleError => {
            let s = (0..axes)
                .map(|k| {
                    let (mut rx, mut xx) = (0.0, 0.0);
                    for i in 0..w.len() {
                        let x = data.base[k][i];
                        rx += w[i] * (data.meas[k][i] - x) * x;
                        xx += w[i] * x * x;
                    }
                    if xx > 0.0 { rx / xx } else { 0.0 }
                })
                .collect();
            Fitted::ScaleError { s }
        }
        Effect::CyclicError => {
            let (mut pitch, mut sn, mut cs) = (Vec::new(), Vec::new(), Vec::new());
            for k in 0..axes {
                crate::numeric::stop::check();
                let x = &data.base[k];
                let r: Vec<f64> = data.meas[k].iter().zip(x).map(|(m, b)| m - b).collect();
                let solve_strided = |p: f64, stride: usize| -> (f64, f64, f64) {
                    let (mut ss, mut sc, mut cc, mut rs, mut rc, mut rr) =
                        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
                    for i in (0..w.len()).step_by(stride) {
                        if w[i] == 0.0 {
                            continue;
                        }
                        let (s, c) = cyclic_phase(x[i], p).sin_cos();
                        ss += s * s;
                        sc += s * c;
                        cc += c * c;
                        rs += r[i] * s;
                        rc += r[i] * c;
                        rr += r[i] * r[i];
                    }
                    let det = ss * cc - sc * sc;
                    if det <= 1e-12 * (ss * cc).max(1e-300) {
                        return (0.0, 0.0, rr);
                    }
                    let a = (rs * cc - rc * sc) / det;
                    let b = (rc * ss - rs * sc) / det;
                    (a, b, rr - a * rs - b * rc)
                };
                // log-spaced pitches from 0.5 mm (first search) up to 64 mm or two thirds of the axis travel
                // (a longer "period" is a smooth trend, not a cyclic error), in log-pitch
                let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &v| {
                    (a.0.min(v), a.1.max(v))
                });
                let top = (hi - lo) / 1.5;
                let (pmin, pmax) = bounds.pitch_mm;
                if top.is_nan() || top < pmin {
                    pitch.push(1.0);
                    sn.push(0.0);
                    cs.push(0.0);
                    continue;
                }
                let top = top.min(pmax);
                let steps = ((top / pmin).ln() / (128f64.ln() / 84.0)).ceil().max(2.0) as usize;
                let grid: Vec<f64> = (0..=steps)
                    .map(|i| pmin.ln() + i as f64 * (top / pmin).ln() / steps as f64)
                    .collect();
                // the pitch search runs on at most ~20,000 samples, the refinement on all
                let stride = (w.len() / 20_000).max(1);
                let coarse: Vec<f64> = grid
                    .iter()
                    .map(|lp| solve_strided(lp.exp(), stride).2)
                    .collect();
                let kbest =
                    (0..grid.len()).fold(0, |a, i| if coarse[i] < coarse[a] { i } else { a });
                let near = [
                    grid[kbest.saturating_sub(1)],
                    grid[kbest],
                    grid[(kbest + 1).min(grid.len() - 1)],
                ];
                let (lp, _) = minimize_on_grid(|lp| solve_strided(lp.exp(), 1).2, &near, 14, 1e-3);
                let (a, b, _) = solve_strided(lp.exp(), 1);
                pitch.push(lp.exp());
                sn.push(a);
                cs.push(b);
            }
            Fitted::CyclicError {
                pitch,
                sin: sn,
                cos: cs,
            }
        }
        Effect::ThermalDrift => {
            let n = w.len();
            let period = data.plants.first().map_or(0.0, |p| p.period_s);
            let duration = (n.max(2) - 1) as f64 * period;
            let fit_tau = |tau: f64| -> (Vec<f64>, f64) {
                let mut rates = Vec::new();
                let mut loss = 0.0;
                for k in 0..axes {
                    crate::numeric::stop::check();
                    let (mut rg, mut gg, mut rr) = (0.0, 0.0, 0.0);
                    for i in 0..n {
                        let g = thermal_basis(i as f64 * period, tau);
                        let r = data.meas[k][i] - data.base[k][i];
                        rg += w[i] * r * g;
                        gg += w[i] * g * g;
                        rr += w[i] * r * r;
                    }
                    let rate = if gg > 0.0 { rg / gg } else { 0.0 };
                    rates.push(rate);
                    loss += rr - rate * rg;
                }
                (rates, loss)
            };
            let mut best = fit_tau(f64::INFINITY);
            let mut best_tau = f64::INFINITY;
            for m in [
                bounds.tau_min_fraction,
                0.1,
                0.2,
                0.3,
                0.5,
                0.7,
                1.0,
                1.5,
                2.0,
                3.0,
                5.0,
            ] {
                let cand = fit_tau(m * duration);
                if cand.1 < best.1 {
                    best = cand;
                    best_tau = m * duration;
                }
            }
            Fitted::ThermalDrift {
                rate: best.0,
                tau: best_tau,
            }
        }
    }
}
