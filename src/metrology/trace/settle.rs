//! Where the *measured* position of a logged run has settled: the stretches in which the axis
//! moves slower than a speed threshold, judged over a window of the minimum settled time; and
//! the reading of a stop, taken at its settled end.
//!
//! Why the end: the threshold says when the axis has *begun* to stand still, not where it
//! stands. A first-order approach (time constant τ) crosses a speed v at a rest of v·τ short
//! of its target: 10 µm at 10 µm/s and τ = 1 s, and a reading averaged from there over a 15 s
//! dwell was 2 µm off in E, R, B and A. The rest decays by exp(−t/τ), so the last samples
//! before the axis moves again are the nearest to where it stopped: the reading is the mean
//! of the stop's last window ([`SettledRun::settled_end`]), the same window the speed rule
//! judged still.
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
    /// The settled stretches of the stop, `[start, end)` each in time order: one, unless
    /// [`merge_stops`] joined several.
    pub stretches: Vec<[usize; 2]>,
}

impl SettledRun {
    /// The stop's reading at its settled end: the mean of its last `read_len` settled samples
    /// (all of them when it has fewer), and the first sample averaged.
    ///
    /// What: the position the axis stood at just before it moved again, mm. Formula:
    /// ȳ = mean of the last `read_len` samples of the stop's settled stretches (from the last
    /// stretch back). With `read_len` = the speed window (2h + 1 samples, about
    /// `min_settled_s`), a first-order approach whose rest was e₁ at the stop's first settled
    /// sample is read e₁·exp(−(D − W)/τ) short at most (D the settled time, W the window):
    /// 10 µm·exp(−6) = 0.02 µm for τ = 1 s, D = 6.5 s; white noise σ gives σ/√(2h + 1).
    ///
    /// Reference: none for logged runs; laser calibration software takes its reading at the
    /// end of a fixed dwell, which this is with the dwell found from the measured motion.
    ///
    /// Known bad cases: a stop shorter than a few τ keeps the rest it ends with (nothing in
    /// the log says where the axis would have gone); a drift during the dwell (thermal) is read
    /// where it ends, not averaged.
    pub fn settled_end(&self, measured_mm: &[f64], read_len: usize) -> (usize, f64) {
        let mut left = read_len.max(1);
        let (mut sum, mut n, mut first) = (0.0, 0_usize, self.end);
        for &[a, b] in self.stretches.iter().rev() {
            let take = left.min(b - a);
            sum += measured_mm[b - take..b].iter().sum::<f64>();
            n += take;
            left -= take;
            first = b - take;
            if left == 0 {
                break;
            }
        }
        if n == 0 {
            return (self.start, self.mean_mm);
        }
        (first, sum / n as f64)
    }
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
/// e₁ ≈ speed_mm_s·τ (τ ≫ W) or less: 10 µm for τ = 1 s at the default 10 µm/s. The stretch's
/// `mean_mm` carries it (e₁·τ/D towards the side approached from, D the stop's length) and
/// serves only to match stops to approaches; the reading is [`SettledRun::settled_end`].
///
/// Reference: none for logged runs (readers of laser software wait a fixed dwell); the
/// threshold-over-a-window rule is ours (issue 23 item 5).
///
/// Known bad cases: a traverse slower than `speed_mm_s` reads as settled; noise whose speed
/// noise nears the threshold breaks one stop into several
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
        if k % 65_536 == 0 {
            crate::numeric::stop::check();
        }
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
            stretches: vec![[start, k]],
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
/// joined mean is over the settled samples of both, and the joined stop keeps both stretches
/// (its reading is taken from the last ones back, [`SettledRun::settled_end`]).
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
                last.stretches.extend(run.stretches);
                continue;
            }
        }
        out.push(run);
    }
    out
}
