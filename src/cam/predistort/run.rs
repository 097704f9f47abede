//! One pre-distortion run's fixed data ([`Run`]) and the simulation of a candidate set of
//! points ([`Eval`]): the points written as a G01 program (kept lines as programmed), its
//! feeds, its interpolation and simulation by the motion core, and the feet of the simulated
//! tool tip on the reference.

use std::collections::BTreeMap;

use super::reference::Reference;
use super::{Error, FEED_DECIMALS, MAX_PERIODS};
use crate::motion::gcode::{Block, Feed, Motion, Pose};
use crate::motion::{Machine, Program, interpolate, simulate_machine};

/// One simulation of a candidate set of points.
pub(super) struct Eval {
    pub feeds: Vec<f64>,
    /// Line tag (point index + 1) of every period of the candidate's command.
    pub line: Vec<u32>,
    /// Interpolation periods of the candidate's own command.
    pub periods: usize,
    /// Simulated axes, padded (at rest at the end) to at least the original's periods.
    pub actual: Vec<Vec<f64>>,
    pub feet: Vec<(f64, [f64; 3])>,
    /// RMS and max of the foot distances, mm.
    pub rms: f64,
    pub max: f64,
}

pub(super) fn round_to(x: f64, decimals: i32) -> f64 {
    let s = 10f64.powi(decimals);
    (x * s).round() / s
}

pub(super) fn ceil_to(x: f64, decimals: i32) -> f64 {
    let s = 10f64.powi(decimals);
    // Guard against x·s landing a hair above an integer by rounding error.
    let y = x * s;
    let r = y.round();
    if (y - r).abs() <= 1e-9 * y.abs().max(1.0) {
        r / s
    } else {
        y.ceil() / s
    }
}

pub(super) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// The G01 program through `pts` from `start` at `feeds` (mm/min), standing `dwells[k]` s at
/// point `k` where that is above zero (a G4 block; `dwells` may be shorter than `pts`, the
/// rest 0); block `k` (and its dwell) carries line `k + 1` so that the interpolation's line
/// tags name the point. A run of points whose source
/// line (`lines`) is in `kept` is replaced by that line's original blocks (rapids, canned
/// cycles: written as programmed), tagged with the run's last point, the first starting at
/// the point before.
pub(super) fn program_of(
    start: [f64; 3],
    pts: &[[f64; 3]],
    feeds: &[f64],
    dwells: &[f64],
    lines: &[usize],
    kept: &BTreeMap<usize, Vec<Block>>,
) -> Program {
    let mut blocks = Vec::with_capacity(pts.len());
    let mut prev = start;
    let mut k = 0;
    while k < pts.len() {
        if let Some(orig) = lines.get(k).and_then(|l| kept.get(l)) {
            let mut j = k;
            while j + 1 < pts.len() && lines.get(j + 1) == lines.get(k) {
                j += 1;
            }
            for (i, b) in orig.iter().enumerate() {
                let mut b = b.clone();
                if i == 0 {
                    b.start.xyz = prev;
                }
                b.line = j + 1;
                prev = b.end.xyz;
                blocks.push(b);
            }
            k = j + 1;
            continue;
        }
        blocks.push(Block {
            line: k + 1,
            motion: Motion::Linear,
            start: Pose {
                xyz: prev,
                a: 0.0,
                c: 0.0,
            },
            end: Pose {
                xyz: pts[k],
                a: 0.0,
                c: 0.0,
            },
            feed: Feed::PerMinute(feeds[k]),
            rtcp: false,
        });
        if let Some(&seconds) = dwells.get(k).filter(|&&s| s > 0.0) {
            let at = Pose {
                xyz: pts[k],
                a: 0.0,
                c: 0.0,
            };
            blocks.push(Block {
                line: k + 1,
                motion: Motion::Dwell { seconds },
                start: at,
                end: at,
                feed: Feed::Rapid,
                rtcp: false,
            });
        }
        prev = pts[k];
        k += 1;
    }
    Program {
        blocks,
        first_a_line: None,
        first_c_line: None,
    }
}

/// The fixed data of one pre-distortion run.
pub(super) struct Run<'a> {
    pub machine: &'a Machine,
    pub period_s: f64,
    pub reference: Reference,
    pub start: [f64; 3],
    /// Programmed feed of each point's block, mm/min.
    pub base_feed: Vec<f64>,
    /// Chord length of each point's segment on the undistorted polyline, mm.
    pub base_len: Vec<f64>,
    /// Arc parameter of each point on the reference, mm.
    pub sigma: Vec<f64>,
    /// Periods of the original interpolation.
    pub orig_periods: usize,
    /// Source line of each point.
    pub lines: Vec<usize>,
    /// Lines written as programmed (see [`predistort_keeping`]) and their original blocks.
    pub kept: BTreeMap<usize, Vec<Block>>,
    /// Dwell at each point, s (the corner stage's stops at inside corners; empty: none).
    pub dwell_s: Vec<f64>,
    /// Duration the compensated program may add, as a fraction of the original's
    /// (`max_duration_ratio − 1`, [`super::PredistortOptions`]).
    pub time_budget: f64,
}

impl Run<'_> {
    /// Feeds (mm/min) of the segments ending at `pts`: the programmed feed scaled by the
    /// chord's length ratio, not below the programmed feed, not above the `max_vel` of any
    /// axis nor the machine's rapid rate (unless the programmed feed already is), rounded up
    /// to [`FEED_DECIMALS`]. (A tiny segment whose point moved far, e.g. the first after a
    /// rapid, would otherwise ask for a feed hundreds of times the programmed one.)
    pub fn feeds(&self, pts: &[[f64; 3]]) -> Vec<f64> {
        self.feeds_with(pts, &self.base_feed)
    }

    /// [`Run::feeds`] with the programmed feeds `base_feed` (mm/min) in place of the run's.
    pub fn feeds_with(&self, pts: &[[f64; 3]], base_feed: &[f64]) -> Vec<f64> {
        let mut prev = self.start;
        let mut out = Vec::with_capacity(pts.len());
        for (k, p) in pts.iter().enumerate() {
            let d = sub(*p, prev);
            let len = norm(d);
            let base = base_feed[k];
            let mut f = base;
            if self.base_len[k] > 0.0 && len > self.base_len[k] {
                f = (base * len / self.base_len[k]).min(self.machine.rapid_mm_min);
                for (i, ax) in self.machine.axes.iter().enumerate().take(3) {
                    if d[i].abs() > 1e-12 {
                        f = f.min(60.0 * ax.limits.max_vel * len / d[i].abs());
                    }
                }
                f = f.max(base);
            }
            out.push(ceil_to(f, FEED_DECIMALS));
            prev = *p;
        }
        out
    }

    /// Interpolates and simulates the points as the service would.
    pub fn evaluate(&self, pts: &[[f64; 3]]) -> Result<Eval, Error> {
        self.evaluate_with(pts, &self.base_feed)
    }

    /// [`Run::evaluate`] with the programmed feeds `base_feed` (mm/min) in place of the run's.
    pub fn evaluate_with(&self, pts: &[[f64; 3]], base_feed: &[f64]) -> Result<Eval, Error> {
        self.evaluate_dwelling(pts, base_feed, &self.dwell_s)
    }

    /// [`Run::evaluate_with`] with the dwells `dwells` (s per point) in place of the run's.
    pub fn evaluate_dwelling(
        &self,
        pts: &[[f64; 3]],
        base_feed: &[f64],
        dwells: &[f64],
    ) -> Result<Eval, Error> {
        let feeds = self.feeds_with(pts, base_feed);
        let program = program_of(self.start, pts, &feeds, dwells, &self.lines, &self.kept);
        let mut cmd = interpolate(&program, self.machine, self.period_s, MAX_PERIODS)?;
        let periods = cmd.t.len();
        let line = std::mem::take(&mut cmd.line);
        for col in cmd.axes.iter_mut() {
            let last = *col.last().unwrap_or(&0.0);
            col.resize(periods.max(self.orig_periods), last);
        }
        let actual = simulate_machine(self.machine, &cmd)?;
        let tips: Vec<[f64; 3]> = (0..actual[0].len())
            .map(|i| [actual[0][i], actual[1][i], actual[2][i]])
            .collect();
        // The arc parameter of the point each period's command heads for (held at the last
        // after the command ends): the foot search's hint where the path retraces itself.
        let last_sigma = self.sigma.last().copied().unwrap_or(0.0);
        let hint: Vec<f64> = (0..tips.len())
            .map(|i| {
                line.get(i)
                    .and_then(|&t| (t as usize).checked_sub(1))
                    .and_then(|k| self.sigma.get(k).copied())
                    .unwrap_or(last_sigma)
            })
            .collect();
        let feet = self.reference.feet_hinted(&tips, Some(&hint));
        let sq: Vec<f64> = feet
            .iter()
            .map(|(_, e)| e.iter().map(|v| v * v).sum::<f64>())
            .collect();
        let rms = (sq.iter().sum::<f64>() / sq.len().max(1) as f64).sqrt();
        let max = sq.iter().fold(0.0f64, |m, v| m.max(*v)).sqrt();
        Ok(Eval {
            feeds,
            line,
            periods,
            actual,
            feet,
            rms,
            max,
        })
    }
}
