//! What is left after the chosen effects (CONTRACT v1.1 "unexplained"): RMS, share of the
//! original squared gap, and the strongest periodic components of the rest, each periodic in
//! time (`period_s`) or in an axis position (`period_mm`), on the axis that carries it.
#![allow(clippy::needless_range_loop)] // index loops over parallel per-sample arrays read clearer

use serde::Serialize;

use crate::numeric::brent::minimize_on_grid;

/// One periodic component of the leftover gap.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Periodic {
    /// Period in time, s (when the component repeats in time).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub period_s: Option<f64>,
    /// Period in the axis' position, mm (when it repeats along the axis).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub period_mm: Option<f64>,
    /// The axis whose leftover gap carries it.
    pub axis: String,
    /// Amplitude (half peak-to-peak of the sinusoid), mm.
    pub amplitude: f64,
}

/// Components reported at most.
pub const MAX_COMPONENTS: usize = 5;
/// Smallest part of an axis' leftover variance a component must explain to be reported.
pub const MIN_EXPLAINED: f64 = 0.05;

/// Solves the 3×3 system `m·x = v` by Cramer's rule; `None` when (nearly) singular.
fn solve3(m: [[f64; 3]; 3], v: [f64; 3]) -> Option<[f64; 3]> {
    let det3 = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det3(m);
    let scale = m[0][0] * m[1][1] * m[2][2];
    if d.abs() <= 1e-12 * scale.abs().max(1e-300) {
        return None;
    }
    let mut x = [0.0; 3];
    for (c, xc) in x.iter_mut().enumerate() {
        let mut a = m;
        for r in 0..3 {
            a[r][c] = v[r];
        }
        *xc = det3(a) / d;
    }
    Some(x)
}

/// Least-squares sinusoid `a·sin φᵢ + b·cos φᵢ + c` at phases `φᵢ = 2π·uᵢ/p` over samples
/// `(0..n).step_by(stride)`; returns `(a, b, c, residual sum of squares)`.
fn sinusoid(u: &[f64], r: &[f64], p: f64, stride: usize) -> (f64, f64, f64, f64) {
    // normal equations of [sin, cos, 1]
    let mut m = [[0.0f64; 3]; 3];
    let mut v = [0.0f64; 3];
    let mut rr = 0.0;
    for i in (0..r.len()).step_by(stride) {
        let (s, c) = (std::f64::consts::TAU * u[i] / p).sin_cos();
        let x = [s, c, 1.0];
        for a in 0..3 {
            for b in 0..3 {
                m[a][b] += x[a] * x[b];
            }
            v[a] += x[a] * r[i];
        }
        rr += r[i] * r[i];
    }
    match solve3(m, v) {
        Some(x) => (
            x[0],
            x[1],
            x[2],
            rr - x[0] * v[0] - x[1] * v[1] - x[2] * v[2],
        ),
        None => (0.0, 0.0, 0.0, rr),
    }
}

/// The best sinusoid of `r` against the coordinate `u` over log-spaced periods in `[lo, hi]`:
/// a grid of ≥ 40 points per decade on at most ~20,000 samples, then Brent on all samples.
/// Returns `(period, amplitude, residual sum of squares)`.
pub(crate) fn best_period(u: &[f64], r: &[f64], lo: f64, hi: f64) -> Option<(f64, f64, f64)> {
    if !(lo > 0.0 && hi > lo * 1.05) {
        return None;
    }
    let steps = ((hi / lo).log10() * 60.0).ceil().max(4.0) as usize;
    let grid: Vec<f64> = (0..=steps)
        .map(|i| lo.ln() + i as f64 * (hi / lo).ln() / steps as f64)
        .collect();
    let stride = (r.len() / 20_000).max(1);
    let coarse: Vec<f64> = grid
        .iter()
        .map(|lp| sinusoid(u, r, lp.exp(), stride).3)
        .collect();
    let k = (0..grid.len()).fold(0, |a, i| if coarse[i] < coarse[a] { i } else { a });
    let near = [
        grid[k.saturating_sub(1)],
        grid[k],
        grid[(k + 1).min(grid.len() - 1)],
    ];
    let (lp, _) = minimize_on_grid(|lp| sinusoid(u, r, lp.exp(), 1).3, &near, 16, 1e-4);
    let (a, b, _, rss) = sinusoid(u, r, lp.exp(), 1);
    Some((lp.exp(), a.hypot(b), rss))
}

/// Strongest periodic components of the leftover gap `rest` (per axis, mm; `pos` the axis
/// positions, mm; samples `period_s` apart). Per axis, greedily: the best sinusoid in time
/// (periods from 10 samples to a third of the block) and in position (0.5 mm to two thirds of
/// the travel), the one that removes more of the leftover is kept and subtracted, up to three
/// per axis, while it explains at least [`MIN_EXPLAINED`] of the axis' leftover variance.
/// The strongest [`MAX_COMPONENTS`] over all axes, largest amplitude first. Bad cases: an axis
/// moving at constant speed makes time and position periods equivalent (time is named then
/// only if it fits better); periods near the block length are trends and are not searched.
pub fn periodic_components(
    rest: &[Vec<f64>],
    pos: &[Vec<f64>],
    axes: &[String],
    period_s: f64,
) -> Vec<Periodic> {
    let mut out = Vec::new();
    for (k, r) in rest.iter().enumerate() {
        let n = r.len();
        if n < 40 {
            continue;
        }
        let mean = r.iter().sum::<f64>() / n as f64;
        let mut r: Vec<f64> = r.iter().map(|v| v - mean).collect();
        let var0: f64 = r.iter().map(|v| v * v).sum();
        if var0 <= 0.0 {
            continue;
        }
        let t: Vec<f64> = (0..n).map(|i| i as f64 * period_s).collect();
        let x = &pos[k];
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &v| {
            (a.0.min(v), a.1.max(v))
        });
        let name = axes.get(k).cloned().unwrap_or_default();
        for _ in 0..3 {
            let rss0: f64 = r.iter().map(|v| v * v).sum();
            let in_time = best_period(&t, &r, 10.0 * period_s, (n - 1) as f64 * period_s / 3.0);
            let in_pos = best_period(x, &r, 0.5, (hi - lo) / 1.5);
            let pick = match (in_time, in_pos) {
                (Some(a), Some(b)) if b.2 < a.2 => (false, b),
                (Some(a), _) => (true, a),
                (None, Some(b)) => (false, b),
                (None, None) => break,
            };
            let (is_time, (p, amp, rss)) = pick;
            if rss0 - rss < MIN_EXPLAINED * var0 {
                break;
            }
            let u = if is_time { &t } else { x };
            let (a, b, c, _) = sinusoid(u, &r, p, 1);
            for i in 0..n {
                let (s, co) = (std::f64::consts::TAU * u[i] / p).sin_cos();
                r[i] -= a * s + b * co + c;
            }
            out.push(Periodic {
                period_s: is_time.then_some(p),
                period_mm: (!is_time).then_some(p),
                axis: name.clone(),
                amplitude: amp,
            });
        }
    }
    out.sort_by(|a, b| b.amplitude.total_cmp(&a.amplitude));
    out.truncate(MAX_COMPONENTS);
    out
}

#[cfg(test)]
mod tests;
