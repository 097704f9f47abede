//! The clock of a time-stamped log: the delay and rate ratio that map its stamps onto the
//! program's time, found by matching the logged positions to the stored simulation.

use std::ops::Range;

use crate::gap::Error;
use crate::numeric::brent::minimize_on_grid;

/// Largest misfit accepted, as a fraction of the log's own motion (RMS about its mean): a log
/// further from the simulation than this at its best clock is not a log of this program.
pub const MAX_MISFIT: f64 = 0.1;
/// Smallest part of the squared misfit a clock drift must remove to be kept (else the rate
/// ratio is 1): a drift that explains less cannot change the diagnosis either.
pub const MIN_RATE_GAIN: f64 = 0.02;
/// Largest clock drift searched: a rate ratio within 1 ± this.
pub const MAX_RATE_DEVIATION: f64 = 0.02;
/// A log whose positions vary by less than this (mm RMS) does not move.
pub const MIN_MOTION_MM: f64 = 0.01;
/// Delays tried by the coarse scan (at least one period apart).
const COARSE_STEPS: f64 = 4000.0;
/// Stretches of the log whose delays the drift test compares.
const DRIFT_WINDOWS: usize = 8;
/// Standard errors the drift's slope must stand from 0.
const DRIFT_T: f64 = 4.0;
/// Log samples the coarse scan reads (evenly strided).
const COARSE_SAMPLES: usize = 2000;
/// Log samples the line search reads.
const FINE_SAMPLES: usize = 20_000;
/// A second basin of the scan, behind a ridge this factor above it, whose refined squared
/// misfit is within this factor of the best makes the alignment ambiguous.
const AMBIGUITY: f64 = 4.0;

/// A log's clock against the program's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clock {
    /// Log-clock time of the program's start, s.
    pub delay_s: f64,
    /// Log seconds per program second.
    pub rate_ratio: f64,
    /// RMS of |log − simulation| over the log's samples at this clock, mm.
    pub residual_rms_mm: f64,
    /// RMS of the log's positions about their mean, mm.
    pub motion_rms_mm: f64,
}

impl Clock {
    /// Program time (s) of log stamp `t` (s): `(t − delay_s) / rate_ratio`.
    pub fn program_time(&self, t: f64) -> f64 {
        (t - self.delay_s) / self.rate_ratio
    }
}

/// The simulation per axis (mm) on the program's grid, read at any program time.
struct Reference<'a> {
    cols: &'a [Vec<f64>],
    period_s: f64,
}

impl Reference<'_> {
    /// Position (mm) and slope (mm/s) of axis `k` at program time `tau` (s): linear between
    /// grid instants, held (slope 0) before the start and after the end.
    fn read(&self, k: usize, tau: f64) -> (f64, f64) {
        let c = &self.cols[k];
        let x = tau / self.period_s;
        let last = c.len() - 1;
        if x.is_nan() || x <= 0.0 {
            return (c[0], 0.0);
        }
        if x >= last as f64 {
            return (c[last], 0.0);
        }
        let i = x as usize;
        let d = c[i + 1] - c[i];
        (c[i] + (x - i as f64) * d, d / self.period_s)
    }
}

/// Program time of a stamp: `τ = a + b·(t − t_c)`.
#[derive(Clone, Copy, Debug)]
struct Params {
    a: f64,
    b: f64,
}

/// What every evaluation shares: the simulation, the stamps, the log, the mean stamp.
struct Fit<'a> {
    reference: Reference<'a>,
    t: &'a [f64],
    log: &'a [Vec<f64>],
    tc: f64,
}

impl Fit<'_> {
    /// `Σ |log_i − sim(τ_i)|²` over every `stride`-th sample (mm²).
    fn sse(&self, p: Params, stride: usize) -> f64 {
        self.sse_on(p, 0..self.t.len(), stride)
    }

    /// As [`Fit::sse`], over the samples `range`.
    fn sse_on(&self, p: Params, range: Range<usize>, stride: usize) -> f64 {
        let mut s = 0.0;
        for i in range.step_by(stride) {
            let tau = p.a + p.b * (self.t[i] - self.tc);
            for (k, col) in self.log.iter().enumerate() {
                let e = col[i] - self.reference.read(k, tau).0;
                s += e * e;
            }
        }
        s
    }

    /// The delay-only misfit of a scan: the program starts at log time `d`.
    fn sse_at_delay(&self, d: f64, stride: usize) -> f64 {
        self.sse(
            Params {
                a: self.tc - d,
                b: 1.0,
            },
            stride,
        )
    }

    /// Gauss–Newton with step halving on `a` (and `b` when `free_rate`) from `p`; returns the
    /// parameters and their misfit (mm²) over every sample.
    fn gauss_newton(&self, p: Params, free_rate: bool) -> (Params, f64) {
        self.gauss_newton_on(p, free_rate, 0..self.t.len()).0
    }

    /// As [`Fit::gauss_newton`], on the samples `range`; also returns `Σ v²` there (mm²/s²,
    /// the information on the delay).
    fn gauss_newton_on(
        &self,
        mut p: Params,
        free_rate: bool,
        range: Range<usize>,
    ) -> ((Params, f64), f64) {
        let mut cur = self.sse_on(p, range.clone(), 1);
        let mut info = 0.0;
        for _ in 0..40 {
            let (mut h00, mut h01, mut h11, mut g0, mut g1) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for i in range.clone() {
                let dt = self.t[i] - self.tc;
                let tau = p.a + p.b * dt;
                for (k, col) in self.log.iter().enumerate() {
                    let (x, v) = self.reference.read(k, tau);
                    let e = col[i] - x;
                    h00 += v * v;
                    h01 += v * v * dt;
                    h11 += v * v * dt * dt;
                    g0 += v * e;
                    g1 += v * e * dt;
                }
            }
            info = h00;
            if h00 <= 0.0 {
                break;
            }
            let det = h00 * h11 - h01 * h01;
            let (da, db) = if free_rate && det > 1e-12 * h00 * h11 {
                ((g0 * h11 - g1 * h01) / det, (g1 * h00 - g0 * h01) / det)
            } else {
                (g0 / h00, 0.0)
            };
            let mut step = 1.0;
            let mut moved = false;
            while step > 1e-4 {
                let q = Params {
                    a: p.a + step * da,
                    b: p.b + step * db,
                };
                let s = self.sse_on(q, range.clone(), 1);
                if s < cur {
                    (p, cur, moved) = (q, s, true);
                    break;
                }
                step *= 0.5;
            }
            if !moved || (step * da).abs() < 1e-10 {
                break;
            }
        }
        ((p, cur), info)
    }

    /// Whether the log's clock drifts against the program's at `p`: the delay refitted on each
    /// of [`DRIFT_WINDOWS`] stretches of the log that move, then a straight line through those
    /// delays against time; a drift when its slope is [`DRIFT_T`] standard errors from 0 (and
    /// above 1 ppm). An effect of the machine shifts the windows' delays back and forth with
    /// the direction of motion; only a clock moves them steadily.
    fn drifts(&self, p: Params) -> bool {
        let n = self.t.len();
        let windows = DRIFT_WINDOWS.min(n / 25);
        let fits: Vec<((Params, f64), f64)> = (0..windows)
            .map(|w| self.gauss_newton_on(p, false, w * n / windows..(w + 1) * n / windows))
            .collect();
        let top = fits.iter().map(|f| f.1).fold(0.0, f64::max);
        let points: Vec<(f64, f64)> = (0..windows)
            .filter(|&w| fits[w].1 > 1e-3 * top)
            .map(|w| {
                let range = w * n / windows..(w + 1) * n / windows;
                let t_mid = self.t[range.clone()].iter().sum::<f64>() / range.len() as f64;
                (t_mid, fits[w].0.0.a - p.a)
            })
            .collect();
        let m = points.len();
        if m < 4 {
            return false;
        }
        let tm = points.iter().map(|p| p.0).sum::<f64>() / m as f64;
        let dm = points.iter().map(|p| p.1).sum::<f64>() / m as f64;
        let stt: f64 = points.iter().map(|p| (p.0 - tm).powi(2)).sum();
        let slope = points.iter().map(|p| (p.0 - tm) * (p.1 - dm)).sum::<f64>() / stt;
        let scatter: f64 = points
            .iter()
            .map(|p| (p.1 - dm - slope * (p.0 - tm)).powi(2))
            .sum::<f64>()
            / (m - 2) as f64;
        let se = (scatter / stt).sqrt();
        slope.abs() > 1e-6 && slope.abs() > DRIFT_T * se
    }
}

/// Estimates the clock of a log (`t` s strictly increasing, `log` per axis mm) against the
/// stored simulation `reference` (per axis, mm, one row every `period_s` from the program's
/// start, held before and after).
///
/// Formula: minimise `Σ_i |log_i − sim(τ_i)|²` with `τ_i = (t_i − delay_s)/rate_ratio`.
/// First a scan of the delay (rate 1) over every overlap of log and program, in at most 4,000
/// steps of at least one period on at most 2,000 samples; then Brent's line search between the
/// best scan point's neighbours (and those of up to five rival basins); then Gauss–Newton on the delay alone and on delay and rate
/// together (Nocedal & Wright 2006 §10.3). The drift is kept when the delays refitted on
/// stretches of the log move steadily with time (a slope 4 standard errors from 0: an effect
/// of the machine moves them back and forth, a clock steadily), when it removes at least
/// `MIN_RATE_GAIN` of the squared misfit and stays within 1 ± `MAX_RATE_DEVIATION`.
/// Reference: Nocedal & Wright, Numerical Optimization (2006), §10.3 (Gauss–Newton).
/// Errors ([`Error::Align`], a sentence): fewer than `MIN_LOG_SAMPLES` samples; a log that does
/// not move; a second, separate delay that fits nearly as well (the motion repeats); a misfit
/// above `MAX_MISFIT` of the log's motion (a log of another program).
/// Known bad cases: a lag that grows with speed alike on every axis (a position-loop gain below
/// the stored one, seen only at constant feed) looks like a later start and is partly taken
/// into `delay_s`; on a single constant-speed move a scale error looks like clock drift.
pub fn estimate_clock(
    reference: &[Vec<f64>],
    period_s: f64,
    t: &[f64],
    log: &[Vec<f64>],
) -> Result<Clock, Error> {
    let n = t.len();
    if n < super::MIN_LOG_SAMPLES {
        return Err(Error::Align(format!(
            "measured has {n} time-stamped samples: at least {} are needed to align a log to \
             the program; send a longer log",
            super::MIN_LOG_SAMPLES
        )));
    }
    let mut spread = 0.0;
    for col in log {
        let mean = col.iter().sum::<f64>() / n as f64;
        spread += col.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>();
    }
    let motion_rms_mm = (spread / n as f64).sqrt();
    if motion_rms_mm < MIN_MOTION_MM {
        return Err(Error::Align(format!(
            "the log does not move (its positions vary by {motion_rms_mm:.4} mm rms): its clock \
             is found from the motion, so log while the program runs"
        )));
    }
    let fit = Fit {
        reference: Reference {
            cols: reference,
            period_s,
        },
        t,
        log,
        tc: t.iter().sum::<f64>() / n as f64,
    };
    let t_ref = (reference[0].len() - 1) as f64 * period_s;
    let span = t_ref + (t[n - 1] - t[0]);
    let h = (span / COARSE_STEPS).max(period_s);
    let delays: Vec<f64> = (0..=(span / h).ceil() as usize)
        .map(|i| t[0] - t_ref + i as f64 * h)
        .collect();
    let stride = (n / COARSE_SAMPLES).max(1);
    let cost: Vec<f64> = delays
        .iter()
        .map(|&d| fit.sse_at_delay(d, stride))
        .collect();
    let best = (0..cost.len()).fold(0, |a, i| if cost[i] < cost[a] { i } else { a });
    // the best basin and its rivals, each refined by a line search on up to 20,000 samples:
    // the scan's own step would blur the comparison
    let fine = (n / FINE_SAMPLES).max(1);
    let refine = |i: usize| {
        let around = [delays[i] - h, delays[i], delays[i] + h];
        minimize_on_grid(|d| fit.sse_at_delay(d, fine), &around, 40, 1e-4)
    };
    let mut basins: Vec<(f64, f64)> = std::iter::once(best)
        .chain(rivals(&cost, best))
        .map(refine)
        .collect();
    basins.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (d, best_sse) = basins[0];
    if let Some(&(other, _)) = basins[1..].iter().find(|(_, s)| *s <= AMBIGUITY * best_sse) {
        return Err(Error::Align(format!(
            "the log fits the program about as well with the program starting at {d:.3} s as at \
             {other:.3} s of the log's clock (the motion repeats): log from before the program's \
             start or over a longer stretch of it"
        )));
    }
    let start = Params {
        a: fit.tc - d,
        b: 1.0,
    };
    let (p1, s1) = fit.gauss_newton(start, false);
    let (p2, s2) = fit.gauss_newton(p1, true);
    let drift = fit.drifts(p1)
        && s2 < (1.0 - MIN_RATE_GAIN) * s1
        && (1.0 / p2.b - 1.0).abs() <= MAX_RATE_DEVIATION;
    let (p, sse) = if drift { (p2, s2) } else { (p1, s1) };
    let clock = Clock {
        delay_s: fit.tc - p.a / p.b,
        rate_ratio: if drift { 1.0 / p.b } else { 1.0 },
        residual_rms_mm: (sse / n as f64).sqrt(),
        motion_rms_mm,
    };
    if clock.residual_rms_mm > MAX_MISFIT * motion_rms_mm {
        return Err(Error::Align(format!(
            "the log does not follow this program: at its best clock (delay_s {:.4}, rate_ratio \
             {:.6}) it differs from the stored simulation by {:.3} mm rms, {:.0}% of its own \
             motion ({:.3} mm rms); is it a log of another program, or in other coordinates?",
            clock.delay_s,
            clock.rate_ratio,
            clock.residual_rms_mm,
            100.0 * clock.residual_rms_mm / motion_rms_mm,
            motion_rms_mm
        )));
    }
    Ok(clock)
}

/// Up to five local minima of the scan `cost` other than `best`, lowest first, each behind a
/// ridge [`AMBIGUITY`] times higher than itself (a separate basin, not a wiggle of the best).
fn rivals(cost: &[f64], best: usize) -> Vec<usize> {
    let mut out: Vec<usize> = (1..cost.len().saturating_sub(1))
        .filter(|&j| j != best && cost[j] < cost[j - 1] && cost[j] <= cost[j + 1])
        .filter(|&j| {
            let (lo, hi) = (j.min(best), j.max(best));
            let ridge = cost[lo..=hi].iter().copied().fold(0.0, f64::max);
            ridge >= AMBIGUITY * cost[j]
        })
        .collect();
    out.sort_by(|&a, &b| cost[a].total_cmp(&cost[b]));
    out.truncate(5);
    out
}
