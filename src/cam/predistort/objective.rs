//! The one objective (issue 39 item 3): distance-weighted contour error along the original
//! path, its max, the band around the path, and time, summed over the model set.
//!
//! Every simulated tool-tip sample is placed on the original path by its foot (module
//! `path`) and weighted by the path length it covers (half the chord to each neighbour), so
//! a slow stretch does not count more for being sampled more. Its distance goes into bins
//! of the path length ([`BIN_MM`]), shared between the two nearest bins by linear (hat)
//! weights so that a small change moves the residuals smoothly. Per model and bin, three
//! residuals:
//! - the RMS term √(Σ w d² / W₀) / (0.3 · RMS₀): its squares sum to (RMS / (0.3 RMS₀))²,
//!   1 at the nominal gate ([`RMS_TARGET`]);
//! - the max term √(Σ w d⁸ / W₀) / (0.5 · max₀)⁴: squares summing to the 8-norm of the
//!   distance over 0.5 max₀, to the 8th power — a smooth stand-in for the max that is 1
//!   where the 8-norm reaches the nominal max gate ([`MAX_TARGET`]);
//! - the band term: a quadratic hinge on how far a sample lies beyond its bound, starting
//!   [`HINGE_WIDTH`] of the band inside it, weighted by [`PENALTY`]. The bound towards
//!   the material (either side where it is not known) is the band, away from it
//!   [`ENVELOPE_MM`]; where the original already went further, its excursion. Where the
//!   original stayed within a bound the bound is a constraint (issue 39 item 1): its hinge
//!   takes the extra weight the penalty method of [`super::predistort_sided`] gives it,
//!   and a sample beyond it is a gouge. Where the original went further, the hinge only
//!   keeps the answer from going further still, and the RMS and max terms judge it.
//!
//! W₀, RMS₀ and max₀ are the nominal original's (its path weight, distance-weighted RMS
//! and 8-norm of the distance) over the bins the answer can change (the focus,
//! [`Objective::set_focus`]: the union of the features' windows); bins outside it hold no
//! residual. Every model is judged in those units: a model on which the original already
//! follows the path (kff + 0.1 on a machine at kff 0.9 is a perfect feed-forward) weighs
//! what the answer costs there in the nominal's units, not as a ratio to its own zero. And
//! an error no feature can change (the servo still catching up with a rapid at a lead-in's
//! start) neither sets the scale nor dilutes the relative improvement the optimiser stops
//! on. The nominal model weighs as much as all others together. One more residual holds the duration of the nominal run
//! under the duration limit: a hinge starting [`TIME_MARGIN`] below it.

use std::ops::Range;

use super::models::Model;
use super::path::{Path, excursions};
use super::{Error, MAX_PERIODS, SETTLE_TIME_CONSTANTS};
use crate::motion::program::Program;
use crate::motion::{PathControl, interpolate_with, simulate_machine};
use crate::numeric::vec3::dist;

/// Bin length along the path, mm: finer than any corner's error region (a servo lags over
/// millimetres), coarse enough to hold a few samples at finishing feeds.
pub const BIN_MM: f64 = 0.05;

/// Most bins; a longer path gets longer bins.
pub const MAX_BINS: usize = 20_000;

/// RMS over the original's at which the RMS term is 1: the nominal gate (0.3).
pub const RMS_TARGET: f64 = 0.3;

/// Share of the original's max at which the max term is 1: the nominal max gate (0.5).
pub const MAX_TARGET: f64 = 0.5;

/// Bound away from the material where the side is known, mm: the tool may leave the path
/// into free space, but a loop of half a millimetre is as far as a finishing pass goes.
pub const ENVELOPE_MM: f64 = 0.5;

/// The band hinge starts this share of the band inside its bound, so the answer keeps
/// clear of it on models other than those simulated.
pub const HINGE_WIDTH: f64 = 0.2;

/// Weight of the band and time hinges against the error terms: a bound is a constraint,
/// ten times the pull of the error that would cross it.
pub const PENALTY: f64 = 10.0;

/// How far along the path, as a multiple of a sample's distance d, its foot may move for
/// a small change of the run: near a corner of interior angle α the nearest points on the
/// two legs lie 2·d / tan(α/2) apart, 7.5·d at 30°, the sharpest corner of the corner grid
/// and the held-out set. A sample counts against the band as a constraint only where the
/// original stayed within it over that stretch, so a corner's error attributed a few bins
/// over is not read as a new excursion.
pub const FOOT_SPREAD: f64 = 7.5;

/// The time hinge starts this share of the original's duration below the limit (2 %): the
/// other models' durations spread about that much around the nominal's.
pub const TIME_MARGIN: f64 = 0.02;

/// What one run of one model gives, per bin and in total.
#[derive(Clone, Debug, Default)]
pub struct Acc {
    /// Σ w d² per bin (mm³).
    pub sq: Vec<f64>,
    /// Σ w d⁸ per bin.
    pub m8: Vec<f64>,
    /// Σ w hinge² per bin.
    pub pen: Vec<f64>,
    /// Σ w per bin (mm).
    pub wt: Vec<f64>,
    /// Periods per bin (the local time).
    pub time: Vec<f64>,
    /// Largest excursion towards the material and away from it, per bin, mm.
    pub ex_in: Vec<f64>,
    /// See `ex_in`.
    pub ex_out: Vec<f64>,
    /// Σ w over cutting samples, mm.
    pub weight: f64,
    /// Σ w d² over cutting samples.
    pub wsq: f64,
    /// Σ d² and count of cutting samples (the per-period RMS).
    pub psq: f64,
    /// See `psq`.
    pub count: usize,
    /// Largest distance on a cutting segment, mm.
    pub max: f64,
    /// Largest excursion beyond a bound the original stayed within (≤ 0: none), mm.
    pub gouge: f64,
    /// Periods of the command.
    pub periods: usize,
    /// Largest distance per program block, mm.
    pub block_max: Vec<f64>,
    /// Σ signed distance towards the centre and count, per arc block.
    pub block_inside: Vec<(f64, usize)>,
}

impl Acc {
    /// Distance-weighted RMS, mm.
    pub fn rms_distance(&self) -> f64 {
        if self.weight > 0.0 {
            (self.wsq / self.weight).sqrt()
        } else {
            0.0
        }
    }

    /// Per-period RMS, mm.
    pub fn rms(&self) -> f64 {
        (self.psq / self.count.max(1) as f64).sqrt()
    }
}

/// A point of the objective.
#[derive(Clone, Debug)]
pub struct Eval {
    /// Residuals: per model, per bin, [RMS, max, band]; the time hinge last.
    pub r: Vec<f64>,
    /// Periods per bin of the nominal run.
    pub time: Vec<f64>,
    /// d(time residual)/d(periods of the nominal run) (0 where the hinge is off).
    pub time_slope: f64,
    /// The runs, one per model.
    pub runs: Vec<Acc>,
}

impl Eval {
    /// Σ r².
    pub fn cost(&self) -> f64 {
        self.r.iter().map(|v| v * v).sum()
    }
}

/// The objective of one program on a model set.
pub struct Objective<'a> {
    /// The original path.
    pub path: Path,
    /// The models.
    pub models: Vec<Model>,
    control: &'a PathControl,
    bin_mm: f64,
    /// Number of bins.
    pub nb: usize,
    band_mm: f64,
    max_ratio: f64,
    allowed_in: Vec<f64>,
    allowed_out: Vec<f64>,
    /// Bins before each bin where the original left the band (towards the material) on
    /// some model (a prefix count, `nb + 1` long): the band is a constraint where there
    /// are none over a sample's [`FOOT_SPREAD`] stretch.
    soft_in: Vec<usize>,
    /// The same for [`ENVELOPE_MM`] away from the material.
    soft_out: Vec<usize>,
    /// The original's run on each model.
    pub base: Vec<Acc>,
    nblocks: usize,
    /// Bins that hold residuals (all until [`Objective::set_focus`]).
    focus: Vec<bool>,
    /// W₀, RMS₀ and the 8-norm max₀ of the nominal original over the focus.
    scale: (f64, f64, f64),
}

impl<'a> Objective<'a> {
    /// The objective of `original` (read with its path-control modes `control`) on `models`,
    /// its path `path`; the band (mm) and the duration limit (× the original's).
    pub fn new(
        original: &Program,
        control: &'a PathControl,
        path: Path,
        models: Vec<Model>,
        band_mm: f64,
        max_ratio: f64,
    ) -> Result<Objective<'a>, Error> {
        let bin_mm = BIN_MM.max(path.total / MAX_BINS as f64);
        let nb = (path.total / bin_mm).ceil() as usize + 2;
        let mut o = Objective {
            path,
            models,
            control,
            bin_mm,
            nb,
            band_mm,
            max_ratio,
            allowed_in: vec![f64::INFINITY; nb],
            allowed_out: vec![f64::INFINITY; nb],
            soft_in: vec![0; nb + 1],
            soft_out: vec![0; nb + 1],
            base: Vec::new(),
            nblocks: original.blocks.len(),
            focus: vec![true; nb],
            scale: (0.0, 0.0, 0.0),
        };
        let base: Vec<Acc> = (0..o.models.len())
            .map(|k| o.run(k, original))
            .collect::<Result<_, _>>()?;
        for b in 0..nb {
            let ex_in = base.iter().map(|a| a.ex_in[b]).fold(0.0, f64::max);
            let ex_out = base.iter().map(|a| a.ex_out[b]).fold(0.0, f64::max);
            o.allowed_in[b] = band_mm.max(ex_in);
            o.allowed_out[b] = ENVELOPE_MM.max(ex_out);
            o.soft_in[b + 1] = o.soft_in[b] + usize::from(ex_in > band_mm);
            o.soft_out[b + 1] = o.soft_out[b] + usize::from(ex_out > ENVELOPE_MM);
        }
        o.base = base;
        o.rescale();
        Ok(o)
    }

    /// Only the bins `windows` cover hold residuals, and the scale (W₀, RMS₀, max₀) is the
    /// nominal original's over them (module docs).
    pub fn set_focus(&mut self, windows: &[Range<usize>]) {
        self.focus = vec![false; self.nb];
        for w in windows {
            for f in &mut self.focus[w.clone()] {
                *f = true;
            }
        }
        self.rescale();
    }

    /// W₀, RMS₀ and the 8-norm max₀ of the nominal original over the focus.
    fn rescale(&mut self) {
        let (mut w, mut sq, mut m8) = (0.0, 0.0, 0.0);
        if let Some(b0) = self.base.first() {
            for b in (0..self.nb).filter(|&b| self.focus[b]) {
                w += b0.wt[b];
                sq += b0.sq[b];
                m8 += b0.m8[b];
            }
        }
        let w = w.max(1e-12);
        self.scale = (w, (sq / w).sqrt(), (m8 / w).powf(0.125));
    }

    /// Bins a path-length window (mm) touches, with the hat's neighbour on each side.
    pub fn bins(&self, w: (f64, f64)) -> Range<usize> {
        let lo = ((w.0 / self.bin_mm).floor().max(0.0) as usize).saturating_sub(1);
        let hi = (((w.1 / self.bin_mm).ceil().max(0.0) as usize) + 2).min(self.nb);
        lo.min(hi)..hi
    }

    /// Residual rows of bins `bins` for every model.
    pub fn rows(&self, bins: &Range<usize>) -> Vec<Range<usize>> {
        (0..self.models.len())
            .map(|k| 3 * (k * self.nb + bins.start)..3 * (k * self.nb + bins.end))
            .collect()
    }

    /// Simulates `program` on model `k` and accumulates its samples.
    pub fn run(&self, k: usize, program: &Program) -> Result<Acc, Error> {
        self.run_with(k, program, self.control, 1.0)
    }

    /// [`Objective::run`] of a program with its own path-control modes (a program text
    /// written from the answer and read back); `band_weight` multiplies the band hinge's
    /// residual where the band is a constraint (1: the objective as documented).
    pub fn run_with(
        &self,
        k: usize,
        program: &Program,
        control: &PathControl,
        band_weight: f64,
    ) -> Result<Acc, Error> {
        let m = &self.models[k];
        let mut cmd = interpolate_with(program, control, &m.machine, m.period_s, MAX_PERIODS)?;
        let periods = cmd.t.len();
        // Hold the last command until the slowest axis has settled.
        let kv = m
            .machine
            .axes
            .iter()
            .map(|a| a.servo.kv)
            .fold(f64::INFINITY, f64::min);
        let extra = (SETTLE_TIME_CONSTANTS / kv / m.period_s).ceil() as usize;
        for c in &mut cmd.axes {
            let last = *c.last().unwrap_or(&0.0);
            c.resize(periods + extra, last);
        }
        let last_line = *cmd.line.last().unwrap_or(&0);
        cmd.line.resize(periods + extra, last_line);
        cmd.t = (0..periods + extra)
            .map(|i| i as f64 * m.period_s)
            .collect();
        let actual = simulate_machine(&m.machine, &cmd)?;
        let n = actual[0].len();
        let nb = self.nb;
        let mut a = Acc {
            sq: vec![0.0; nb],
            m8: vec![0.0; nb],
            pen: vec![0.0; nb],
            wt: vec![0.0; nb],
            time: vec![0.0; nb],
            ex_in: vec![0.0; nb],
            ex_out: vec![0.0; nb],
            periods,
            gouge: f64::NEG_INFINITY,
            block_max: vec![0.0; self.nblocks],
            block_inside: vec![(0.0, 0); self.nblocks],
            ..Acc::default()
        };
        let tip = |i: usize| {
            [
                actual[0][i],
                actual.get(1).map_or(0.0, |c| c[i]),
                actual.get(2).map_or(0.0, |c| c[i]),
            ]
        };
        let hinge_start = HINGE_WIDTH * self.band_mm;
        let w2 = band_weight * band_weight;
        let (mut cursor, mut s_prev) = (0, 0.0);
        for i in 0..n {
            let q = tip(i);
            let Some(foot) = self.path.foot(q, cursor, s_prev) else {
                continue;
            };
            cursor = foot.seg;
            s_prev = foot.s;
            let seg = &self.path.segs[foot.seg];
            let x = (foot.s / self.bin_mm - 0.5).max(0.0);
            let b0 = (x.floor() as usize).min(nb - 2);
            let fr = (x - b0 as f64).clamp(0.0, 1.0);
            let hats = [(b0, 1.0 - fr), (b0 + 1, fr)];
            let during = i < periods;
            for &(b, h) in &hats {
                if during {
                    a.time[b] += h;
                }
            }
            if !seg.cutting {
                continue;
            }
            let back = if i > 0 { dist(q, tip(i - 1)) } else { 0.0 };
            let fwd = if i + 1 < n { dist(tip(i + 1), q) } else { 0.0 };
            let w = 0.5 * (back + fwd);
            let d = foot.dist;
            let (ex_in, ex_out) = excursions(&foot, seg.side);
            // The band is a constraint for this sample where the original stayed within it
            // over the stretch its foot may move by (FOOT_SPREAD).
            let hard = |prefix: &[usize], ex: f64| {
                let w = FOOT_SPREAD * ex;
                let lo = ((foot.s - w) / self.bin_mm - 0.5).floor().max(0.0) as usize;
                let hi =
                    (((foot.s + w) / self.bin_mm - 0.5).ceil().max(0.0) as usize + 1).min(nb - 1);
                let lo = lo.min(hi);
                prefix[hi + 1] == prefix[lo]
            };
            let (hard_in, hard_out) = (hard(&self.soft_in, ex_in), hard(&self.soft_out, ex_out));
            a.weight += w;
            a.wsq += w * d * d;
            a.psq += d * d;
            a.count += 1;
            a.max = a.max.max(d);
            a.block_max[seg.block] = a.block_max[seg.block].max(d);
            if let super::path::Geom::Arc { sweep, .. } = seg.geom {
                let e = &mut a.block_inside[seg.block];
                e.0 += foot.lateral * sweep.signum();
                e.1 += 1;
            }
            let d2 = d * d;
            let d8 = d2 * d2 * d2 * d2;
            for &(b, h) in &hats {
                a.wt[b] += h * w;
                a.sq[b] += h * w * d2;
                a.m8[b] += h * w * d8;
                a.ex_in[b] = a.ex_in[b].max(ex_in);
                a.ex_out[b] = a.ex_out[b].max(ex_out);
                let over_in = ex_in - (self.allowed_in[b] - hinge_start);
                let over_out = ex_out - (self.allowed_out[b] - hinge_start);
                let w_in = if hard_in { w2 } else { 1.0 };
                let w_out = if hard_out { w2 } else { 1.0 };
                let hin = w_in * over_in.max(0.0).powi(2) + w_out * over_out.max(0.0).powi(2);
                a.pen[b] += h * w * hin;
                if hard_in {
                    a.gouge = a.gouge.max(ex_in - self.allowed_in[b]);
                }
                if hard_out {
                    a.gouge = a.gouge.max(ex_out - self.allowed_out[b]);
                }
            }
        }
        if !a.gouge.is_finite() {
            a.gouge = 0.0;
        }
        Ok(a)
    }

    /// The objective of `program`, the band hinge's residual multiplied by `band_weight`
    /// where the band is a constraint (1: the objective as documented).
    pub fn eval(&self, program: &Program, band_weight: f64) -> Result<Eval, Error> {
        let runs: Vec<Acc> = (0..self.models.len())
            .map(|k| self.run_with(k, program, self.control, band_weight))
            .collect::<Result<_, _>>()?;
        let km = self.models.len();
        let mut r = vec![0.0; 3 * km * self.nb + 1];
        let (w0, rms0, max0) = self.scale;
        let rms0 = RMS_TARGET * rms0.max(1e-9);
        let max4 = (MAX_TARGET * max0.max(1e-9)).powi(4);
        for (k, run) in runs.iter().enumerate() {
            let omega = if k == 0 { 1.0 } else { 1.0 / (km - 1) as f64 };
            let sw = omega.sqrt();
            for b in (0..self.nb).filter(|&b| self.focus[b]) {
                let row = 3 * (k * self.nb + b);
                r[row] = sw * (run.sq[b] / w0).sqrt() / rms0;
                r[row + 1] = sw * (run.m8[b] / w0).sqrt() / max4;
                r[row + 2] = sw * PENALTY * (run.pen[b] / w0).sqrt() / self.band_mm;
            }
        }
        let t0 = self.base[0].periods.max(1) as f64;
        let start = self.max_ratio - TIME_MARGIN;
        let ratio = runs[0].periods as f64 / t0;
        let over = ratio - start;
        let last = r.len() - 1;
        r[last] = PENALTY * over.max(0.0) / TIME_MARGIN;
        let time_slope = if over > 0.0 {
            PENALTY / TIME_MARGIN / t0
        } else {
            0.0
        };
        Ok(Eval {
            r,
            time: runs[0].time.clone(),
            time_slope,
            runs,
        })
    }
}
