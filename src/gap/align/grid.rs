//! A log on the program's grid: its gaps, its values at the grid instants it observes, and the
//! gap statistics, residual and noise input of a diagnosis whose grid is only partly observed.

use std::borrow::Cow;

use crate::gap::motion::{GapStats, gap_stats};

/// Per interval `[τ_j, τ_{j+1}]` of the log (program times, s, increasing): whether it is a gap,
/// i.e. longer than [`super::GAP_FACTOR`] times the median interval.
/// Formula: `gap_j = τ_{j+1} − τ_j > 3·median(Δτ)`. Reference: none (a rule of thumb: jitter
/// of a third of the step never trips it). Known bad cases: a log with gaps in more than half
/// its intervals has a gap-sized median and reports none.
pub fn gaps(tau: &[f64]) -> Vec<bool> {
    let mut steps: Vec<f64> = tau.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return Vec::new();
    }
    let mid = steps.len() / 2;
    let median = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
    tau.windows(2)
        .map(|w| w[1] - w[0] > super::GAP_FACTOR * median)
        .collect()
}

/// The log (`tau` program times s, `log` per axis mm, `gap` per interval) at the first
/// `n_grid` instants `i·period_s`: `(measured per axis, weight per instant)`.
///
/// An instant is observed (weight 1) when a log sample lies within half a period of it; its
/// value is the simulation there plus the log's departure from the simulation, taken on the
/// interval on its side of the nearest sample (interpolation), or on the other side's interval
/// when that one is a gap (extrapolation by at most half a period).
/// Unobserved instants hold the `reference` (the stored simulation) with weight 0: placeholders
/// no fit, score or statistic reads.
/// Formula: `m(g) = s(g) + r_j + (g − τ_j)·(r_{j'} − r_j)/(τ_{j'} − τ_j)`, `r = m − s`, `s` the
/// simulation (linear between grid instants), `j` the nearest sample.
/// Reference: linear interpolation (first-order hold) of the sampled positions.
/// Known bad cases: a sample with a gap on both sides observes nothing; a log much slower than
/// the grid observes one instant in many (the fit then sees only those).
pub fn resample(
    reference: &[Vec<f64>],
    period_s: f64,
    tau: &[f64],
    log: &[Vec<f64>],
    gap: &[bool],
    n_grid: usize,
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut measured: Vec<Vec<f64>> = reference.iter().map(|c| c[..n_grid].to_vec()).collect();
    let mut observed = vec![0.0; n_grid];
    let n = tau.len();
    let half = 0.5 * period_s * (1.0 + 1e-9);
    let usable = |j: usize| j + 1 < n && !gap[j];
    let mut k = 0;
    for (i, w) in observed.iter_mut().enumerate() {
        let g = i as f64 * period_s;
        while k + 1 < n && tau[k + 1] <= g {
            k += 1;
        }
        // nearest sample
        let near = if k + 1 < n && (tau[k + 1] - g) < (g - tau[k]).abs() {
            k + 1
        } else {
            k
        };
        let dist = g - tau[near];
        if dist.abs() > half {
            continue;
        }
        // the interval on g's side of the sample, else the other one
        let (side, other) = if dist >= 0.0 {
            (Some(near), near.checked_sub(1))
        } else {
            (near.checked_sub(1), Some(near))
        };
        let Some(j) = side.filter(|&j| usable(j)).or(other.filter(|&j| usable(j))) else {
            continue;
        };
        // interpolate the log's departure from the simulation, not the log itself: the
        // departure is smooth where the motion is not (a 125 Hz log through a rapid's
        // acceleration would be off by microns)
        for ((m, col), sim) in measured.iter_mut().zip(log).zip(reference) {
            let gap_at = |q: usize| col[q] - read(sim, period_s, tau[q]);
            let slope = (gap_at(j + 1) - gap_at(j)) / (tau[j + 1] - tau[j]);
            m[i] = sim[i] + gap_at(near) + dist * slope;
        }
        *w = 1.0;
    }
    (measured, observed)
}

/// The simulation `sim` (one value every `period_s` from 0) at time `tau`, linear between
/// instants and held outside.
pub(super) fn read(sim: &[f64], period_s: f64, tau: f64) -> f64 {
    let x = (tau / period_s).max(0.0);
    let last = sim.len() - 1;
    if x >= last as f64 {
        return sim[last];
    }
    let i = x as usize;
    sim[i] + (x - i as f64) * (sim[i + 1] - sim[i])
}

/// [`gap_stats`] over the observed samples only (`observed` weights 0/1; `None` = all), mm.
/// Formula: `rms = √(Σ_{w_i=1} |m_i − s_i|² / #{w_i = 1})`, `max` over the same samples.
/// Reference: the HTTP contract's `gap_before`. Known bad cases: none observed gives 0.
pub fn masked_stats(
    measured: &[Vec<f64>],
    simulated: &[Vec<f64>],
    observed: Option<&[f64]>,
) -> GapStats {
    match observed {
        None => gap_stats(measured, simulated),
        Some(w) => gap_stats(
            &observed_only(Cow::Borrowed(measured), Some(w)),
            &observed_only(Cow::Borrowed(simulated), Some(w)),
        ),
    }
}

/// The observed samples of per-axis columns, in order (`None`: the columns unchanged) — the
/// residual the noise estimate reads, without the instants no log sample backs.
pub fn observed_only<'a>(
    cols: Cow<'a, [Vec<f64>]>,
    observed: Option<&[f64]>,
) -> Cow<'a, [Vec<f64>]> {
    match observed {
        None => cols,
        Some(w) => Cow::Owned(
            cols.iter()
                .map(|c| {
                    c.iter()
                        .zip(w)
                        .filter(|(_, w)| **w > 0.0)
                        .map(|(v, _)| *v)
                        .collect()
                })
                .collect(),
        ),
    }
}

/// A residual (per axis, mm) with its unobserved samples filled by linear interpolation
/// between the observed ones either side (held before the first and after the last), for the
/// localisation and the periodic search, which read every instant; `None`: unchanged.
/// Formula: `r_i = r_a + (i − a)/(b − a)·(r_b − r_a)` for observed neighbours `a < i < b`.
/// Reference: linear interpolation. Known bad cases: a gap hides whatever the residual did
/// inside it.
pub fn fill_unobserved<'a>(
    residual: &'a [Vec<f64>],
    observed: Option<&[f64]>,
) -> Cow<'a, [Vec<f64>]> {
    let Some(w) = observed else {
        return Cow::Borrowed(residual);
    };
    let seen: Vec<usize> = (0..w.len()).filter(|&i| w[i] > 0.0).collect();
    let (Some(&first), Some(&last)) = (seen.first(), seen.last()) else {
        return Cow::Borrowed(residual);
    };
    Cow::Owned(
        residual
            .iter()
            .map(|r| {
                let mut out = r.clone();
                out[..first].fill(r[first]);
                out[last..].fill(r[last]);
                for pair in seen.windows(2) {
                    let (a, b) = (pair[0], pair[1]);
                    for (i, o) in out.iter_mut().enumerate().take(b).skip(a + 1) {
                        let f = (i - a) as f64 / (b - a) as f64;
                        *o = r[a] + f * (r[b] - r[a]);
                    }
                }
                out
            })
            .collect(),
    )
}
