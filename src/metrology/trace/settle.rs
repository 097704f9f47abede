//! Where the *measured* position of a logged run has settled: the stretches in which the axis
//! moves slower than a speed threshold, judged over a window of the minimum settled time.
//!
//! Why the measured position and not the command: drives log the command as the target itself,
//! written when the move starts, so the command holds still while a slow axis is still
//! travelling (tens of seconds), and a measuring device with its own sample clock drifts
//! against the command's sample index (3 % is 80 s over a 45-minute run). Only the measured
//! motion says when and where the axis stood still.

/// A stretch of samples where the measured position has settled (or two such stretches of one
/// stop, see [`merge_stops`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SettledRun {
    /// First settled sample (measured series).
    pub start: usize,
    /// One past the last settled sample.
    pub end: usize,
    /// Mean measured position over the settled samples, mm.
    pub mean_mm: f64,
    /// Settled samples averaged (fewer than `end - start` after a merge: the samples between
    /// two settled stretches of one stop are left out).
    pub count: usize,
}

/// Half-width, in samples, of the window over which the speed is judged: the window spans
/// about `min_settled_s`, at least 3 samples, at most the run.
pub fn half_window(period_s: f64, min_settled_s: f64, n: usize) -> usize {
    let h = (min_settled_s / (2.0 * period_s)).round();
    if h.is_finite() {
        (h as usize).clamp(1, n.max(1))
    } else {
        n.max(1)
    }
}

/// The settled stretches of a measured position series, in time order.
///
/// A sample k is settled when the speed over the window `[k − h, k + h]` (h from
/// `half_window`, so the window lasts about `min_settled_s`) is at most `speed_mm_s`; a
/// stretch is a maximal run of settled samples, less its first h samples (at most half of it):
/// every sample averaged has had the axis judged still over a whole window before it, and
/// half a window after it (so the departure is left out too).
///
/// Formula: speed_k = |ȳ(k+1..=k+h) − ȳ(k−h..k)| / ((h + 1) T), the difference of the means of
/// the window's two halves over the distance between their centres (unbiased for a constant
/// speed; its noise is σ·sqrt(2/h) / ((h + 1) T) for white noise σ). Sums from prefix sums of
/// y − y₀ (f64, 5 million samples of ±1 m keep the speed to 1e-7 mm/s).
///
/// The rest of a first-order approach (time constant τ) at the first settled sample is about
/// e₁ ≈ speed_mm_s·τ (τ ≫ W) or less; it has decayed by exp(−W/2τ) at the first sample
/// averaged, and biases the reading by about e₁·exp(−W/2τ)·τ/D towards the side approached
/// from (D the stop's length): 0.04 µm for τ = 0.125 s, D = 1.2 s at the defaults.
///
/// Reference: none for logged runs (readers of laser software wait a fixed dwell); the
/// threshold-over-a-window rule is ours (issue 23 item 5).
///
/// Known bad cases: a traverse slower than `speed_mm_s` reads as settled; a sluggish axis
/// (τ ≳ W) keeps a bias of about speed_mm_s·τ²/D (1.9 µm at τ = 0.5 s, D = 1 s: lower
/// `speed_mm_s`); noise whose speed noise nears the threshold breaks one stop into several
/// stretches (joined again by [`merge_stops`]); a series shorter than a window has no
/// settled sample.
pub fn settled_runs(
    measured_mm: &[f64],
    period_s: f64,
    speed_mm_s: f64,
    min_settled_s: f64,
) -> Vec<SettledRun> {
    let n = measured_mm.len();
    let h = half_window(period_s, min_settled_s, n);
    if n < 2 * h + 1 {
        return Vec::new();
    }
    let y0 = measured_mm[0];
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    let mut acc = 0.0;
    for y in measured_mm {
        acc += y - y0;
        prefix.push(acc);
    }
    let limit = speed_mm_s * (h + 1) as f64 * period_s * h as f64;
    let still = |k: usize| {
        let left = prefix[k] - prefix[k - h];
        let right = prefix[k + 1 + h] - prefix[k + 1];
        (right - left).abs() <= limit
    };
    let mut runs = Vec::new();
    let mut k = h;
    while k < n - h {
        if !still(k) {
            k += 1;
            continue;
        }
        let first = k;
        while k < n - h && still(k) {
            k += 1;
        }
        // The first settled sample's window still reaches back into the approach; from half a
        // window on, the axis has been still for a whole window before the sample averaged.
        let start = first + h.min((k - first) / 2);
        let sum: f64 = measured_mm[start..k].iter().sum();
        runs.push(SettledRun {
            start,
            end: k,
            mean_mm: sum / (k - start) as f64,
            count: k - start,
        });
    }
    runs
}

/// Two settled stretches are one stop when the measured position between them never leaves
/// this distance from the first, mm: a reversal through an overrun moves farther, noise and
/// creep within one stop do not.
pub const SAME_STOP_MM: f64 = 0.05;

/// Joins consecutive settled stretches that belong to one stop (the measured position between
/// them stays within [`SAME_STOP_MM`] of the first's mean, and so does the second's mean); the
/// joined mean is over the settled samples of both.
///
/// Known bad cases: a reversal whose overrun is shorter than [`SAME_STOP_MM`] is taken for one
/// stop (ISO 230-2 overruns are millimetres).
pub fn merge_stops(measured_mm: &[f64], runs: Vec<SettledRun>) -> Vec<SettledRun> {
    let mut out: Vec<SettledRun> = Vec::with_capacity(runs.len());
    for run in runs {
        if let Some(last) = out.last_mut() {
            let near = |y: f64| (y - last.mean_mm).abs() <= SAME_STOP_MM;
            if near(run.mean_mm) && measured_mm[last.end..run.start].iter().all(|&y| near(y)) {
                let total = last.mean_mm * last.count as f64 + run.mean_mm * run.count as f64;
                last.count += run.count;
                last.mean_mm = total / last.count as f64;
                last.end = run.end;
                continue;
            }
        }
        out.push(run);
    }
    out
}
