//! Measured logs on their own clock, for the self-check: a truth plant's measured trace (on the
//! command's clock) re-sampled the way a separate logger records it — another sample rate, a
//! delay, jitter on the sampling instants — with the log's own time stamps.
//!
//! The diagnosis of such a log needs its delay and rate estimated (the aligned path of branch
//! gap-clocks); until then [`naive_on_command_clock`] is what a user without that path would
//! send: the log interpolated at the command's sample times, its stamps taken as command time.

use rand::{Rng, RngExt};

/// How a logger's clock differs from the command's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockSpec {
    /// The log is late: a sample stamped `t` was taken at `t − delay_s` on the command clock, s.
    pub delay_s: f64,
    /// The log's nominal sample period, s.
    pub period_s: f64,
    /// Standard deviation of the true sampling instants about the nominal ones, s (not seen
    /// in the stamps).
    pub jitter_s: f64,
}

/// A measured log on its own clock.
#[derive(Clone, Debug)]
pub struct ClockLog {
    /// Time stamps of the samples, s (the log's clock: nominal instants plus the delay).
    pub t: Vec<f64>,
    /// Measured positions per axis at the stamps, mm.
    pub measured: Vec<Vec<f64>>,
    /// The clock the log was drawn with.
    pub spec: ClockSpec,
}

/// Draws a logger clock for a command sampled every `cmd_period_s`: period 0.5–4 × the
/// command's (never within 5 % of it), delay 2–30 ms, jitter 0–10 % of the log's period.
pub fn draw_clock(cmd_period_s: f64, rng: &mut impl Rng) -> ClockSpec {
    let ratio = loop {
        let r: f64 = rng.random_range(0.5..4.0);
        if (r - 1.0).abs() > 0.05 {
            break r;
        }
    };
    let period_s = cmd_period_s * ratio;
    ClockSpec {
        delay_s: rng.random_range(0.002..0.030),
        period_s,
        jitter_s: period_s * rng.random_range(0.0..0.1),
    }
}

/// Catmull-Rom interpolation of `x` (samples `period` s apart, first at 0) at time `s` (s),
/// held at the ends.
///
/// Formula: `p(f) = ½[2p₁ + (p₂ − p₀)f + (2p₀ − 5p₁ + 4p₂ − p₃)f² + (3p₁ − p₀ − 3p₂ + p₃)f³]`.
/// Reference: Catmull & Rom, "A class of local interpolating splines" (1974).
/// Known bad cases: a step in `x` (a play taking up its slack within one sample) under- and
/// overshoots by up to 2/27 ≈ 7.4 % of the step in the samples next to it.
pub fn interpolate(x: &[f64], period: f64, s: f64) -> f64 {
    let n = x.len();
    if n == 0 {
        return 0.0;
    }
    let u = (s / period).clamp(0.0, (n - 1) as f64);
    let i = (u.floor() as usize).min(n.saturating_sub(2));
    let f = u - i as f64;
    let at = |j: isize| x[j.clamp(0, n as isize - 1) as usize];
    let (p0, p1, p2, p3) = (
        at(i as isize - 1),
        at(i as isize),
        at(i as isize + 1),
        at(i as isize + 2),
    );
    0.5 * (2.0 * p1
        + (p2 - p0) * f
        + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f * f
        + (3.0 * p1 - p0 - 3.0 * p2 + p3) * f * f * f)
}

/// Re-samples a noise-free measured trace `trace` (per axis, mm, samples `period` s apart on the
/// command clock) as a logger with clock `spec` records it, plus Gaussian noise `sigma` (mm).
/// Sample `k` is taken at `s_k = k·T_log + j_k` (`j_k` ~ N(0, jitter), clamped into the trace)
/// and stamped `t_k = k·T_log + delay`.
pub fn resample(
    trace: &[Vec<f64>],
    period: f64,
    spec: &ClockSpec,
    sigma: f64,
    rng: &mut impl Rng,
) -> ClockLog {
    let n = trace.first().map_or(0, Vec::len);
    let end = n.saturating_sub(1) as f64 * period;
    let count = (end / spec.period_s).floor() as usize + 1;
    let jitter = rand_distr::Normal::new(0.0, spec.jitter_s.max(1e-15)).expect("valid jitter");
    let noise = rand_distr::Normal::new(0.0, sigma.max(1e-12)).expect("valid sigma");
    let instants: Vec<f64> = (0..count)
        .map(|k| (k as f64 * spec.period_s + rng.sample(jitter)).clamp(0.0, end))
        .collect();
    let measured = trace
        .iter()
        .map(|col| {
            instants
                .iter()
                .map(|&s| interpolate(col, period, s) + rng.sample(noise))
                .collect()
        })
        .collect();
    ClockLog {
        t: (0..count)
            .map(|k| k as f64 * spec.period_s + spec.delay_s)
            .collect(),
        measured,
        spec: *spec,
    }
}

/// The log linearly interpolated at the command's `n` sample times `i·period` (s), its stamps
/// read as command time (no delay estimated), held before the first and after the last stamp:
/// what today's diagnosis is given for a log on another clock.
pub fn naive_on_command_clock(log: &ClockLog, n: usize, period: f64) -> Vec<Vec<f64>> {
    log.measured
        .iter()
        .map(|col| {
            let mut j = 0;
            (0..n)
                .map(|i| {
                    let t = i as f64 * period;
                    while j + 2 < log.t.len() && log.t[j + 1] < t {
                        j += 1;
                    }
                    if col.len() < 2 || t <= log.t[0] {
                        return col.first().copied().unwrap_or(0.0);
                    }
                    let (t0, t1) = (log.t[j], log.t[j + 1]);
                    let f = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
                    col[j] + f * (col[j + 1] - col[j])
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests;
