//! What the leftover gap looks like when no library effect explains it (issue 23, item 2):
//! periodic in time or in an axis' position (any shape, not only a sinusoid), tied to an
//! event (reversal, start, stop), to speed, to direction, to position, or a sudden jump.
//!
//! Every shape is a table of values indexed by a group: a bin of phase, of time since an
//! event, of signed speed, of direction, of position; `prediction = sign·h[group]` (the sign
//! flips event responses with the direction of the motion). Each shape is scored like the
//! effects: fitted on `FOLDS − 1` contiguous time folds and scored on the held-out one, as the
//! fraction of the axis' leftover variance it removes there. A shape that only memorises the
//! block (a position table on a single pass) does not carry over to another fold and scores
//! low. Written here (no crate): binned means with a sign, a few lines each.
#![allow(clippy::needless_range_loop)] // index loops over parallel per-sample arrays read clearer

use serde::Serialize;

use crate::gap::events::axis_events;
use crate::gap::unexplained::best_period;

/// What a pattern is tied to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PatternKind {
    /// Repeats in time (`period_s`).
    PeriodicTime,
    /// Repeats along an axis' position (`period_mm`, axis `of`).
    PeriodicPosition,
    /// A response after each event of axis `of` (`event`: reversal, start or stop), signed by
    /// the direction of the motion.
    Event,
    /// A function of axis `of`'s signed speed.
    Speed,
    /// Follows axis `of`'s direction of motion (two levels).
    Direction,
    /// A function of axis `of`'s position (not periodic).
    Position,
    /// A lasting jump at one sample (lost counts, a knock, a sensor re-reference).
    Jump,
}

/// One pattern of the leftover gap.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Pattern {
    /// What it is tied to.
    pub kind: PatternKind,
    /// The axis whose leftover gap carries it.
    pub axis: String,
    /// The axis whose motion it follows (position, speed, direction, event, period in mm).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub of: Option<String>,
    /// Held-out fraction of the axis' leftover variance it removes (in-sample for a jump).
    pub explained: f64,
    /// Half the peak-to-peak of its shape, mm.
    pub amplitude: f64,
    /// Period in time, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub period_s: Option<f64>,
    /// Period along `of`, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub period_mm: Option<f64>,
    /// The event: "reversal", "start" or "stop".
    #[serde(skip_serializing_if = "Option::is_none")]
    pub event: Option<String>,
    /// Where a jump happens, s from the block's start.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub at_s: Option<f64>,
    /// One sentence for the user.
    pub description: String,
}

/// Contiguous time folds of the held-out score.
pub const FOLDS: usize = 5;
/// Smallest held-out explained fraction a pattern needs to be reported.
pub const MIN_EXPLAINED: f64 = 0.25;
/// Patterns reported at most.
pub const MAX_PATTERNS: usize = 5;
/// Bins of phase, speed and position tables.
const BINS: usize = 16;
/// Window after an event, s, cut into log-spaced bins.
const EVENT_WINDOW_S: f64 = 0.5;
const EVENT_BINS: usize = 20;

/// A shape to score: group per sample (`None`: predicts 0) and sign per sample.
struct Shape {
    groups: Vec<Option<usize>>,
    signs: Vec<f64>,
    count: usize,
}

/// Held-out explained fraction of `r` (mean removed) by `shape` over [`FOLDS`] contiguous
/// folds, and the table fitted on all samples. Formula: `h[g] = Σ sᵢrᵢ / Σ sᵢ²` over the
/// group's training samples; explained `= 1 − Σ_held (r − s·h)² / Σ r²`.
fn score(r: &[f64], shape: &Shape) -> (f64, Vec<f64>) {
    let n = r.len();
    let g = shape.count;
    let fold_of = |i: usize| i * FOLDS / n;
    let mut num = vec![vec![0.0; g]; FOLDS];
    let mut den = vec![vec![0.0; g]; FOLDS];
    for i in 0..n {
        if let Some(k) = shape.groups[i] {
            let s = shape.signs[i];
            num[fold_of(i)][k] += s * r[i];
            den[fold_of(i)][k] += s * s;
        }
    }
    let total = |v: &Vec<Vec<f64>>, k: usize| v.iter().map(|f| f[k]).sum::<f64>();
    let all: Vec<f64> = (0..g)
        .map(|k| {
            let d = total(&den, k);
            if d > 0.0 { total(&num, k) / d } else { 0.0 }
        })
        .collect();
    let (mut left, mut var) = (0.0, 0.0);
    for i in 0..n {
        var += r[i] * r[i];
        let pred = shape.groups[i].map_or(0.0, |k| {
            let f = fold_of(i);
            let d = total(&den, k) - den[f][k];
            if d > 0.0 {
                shape.signs[i] * (total(&num, k) - num[f][k]) / d
            } else {
                0.0
            }
        });
        left += (r[i] - pred) * (r[i] - pred);
    }
    let explained = if var > 0.0 { 1.0 - left / var } else { 0.0 };
    (explained, all)
}

fn half_range(h: &[f64]) -> f64 {
    let (lo, hi) = h.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &v| {
        (a.0.min(v), a.1.max(v))
    });
    if lo.is_finite() { 0.5 * (hi - lo) } else { 0.0 }
}

fn bin(v: f64, lo: f64, hi: f64) -> Option<usize> {
    (hi > lo).then(|| (((v - lo) / (hi - lo) * BINS as f64) as usize).min(BINS - 1))
}

/// Signed FOH speed of a command column, mm per sample (the last sample repeats).
fn speed(c: &[f64]) -> Vec<f64> {
    let n = c.len();
    (0..n)
        .map(|i| if i + 1 < n { c[i + 1] - c[i] } else { 0.0 })
        .map(|v| if v.is_finite() { v } else { 0.0 })
        .collect()
}

/// The best single jump of `r`: (sample, size mm, variance fraction it removes).
fn best_jump(r: &[f64]) -> Option<(usize, f64, f64)> {
    let n = r.len();
    let total: f64 = r.iter().sum();
    let var: f64 = r.iter().map(|v| v * v).sum::<f64>() - total * total / n as f64;
    if n < 20 || var <= 0.0 {
        return None;
    }
    let (mut acc, mut best) = (0.0, (0, 0.0, 0.0));
    let margin = (n / 50).max(5);
    for i in 0..n - 1 {
        acc += r[i];
        let (a, b) = ((i + 1) as f64, (n - i - 1) as f64);
        if i + 1 < margin || n - i - 1 < margin {
            continue;
        }
        // between-group sum of squares of a split after sample i
        let gain = (acc / a - (total - acc) / b).powi(2) * a * b / n as f64;
        if gain > best.2 {
            best = (i + 1, (total - acc) / b - acc / a, gain);
        }
    }
    Some((best.0, best.1, best.2 / var))
}

/// The patterns of the leftover gap `rest` (per axis, mm) of a block commanded `cmd` (per
/// axis, mm; `pos` the simulated positions), samples `period_s` apart: per axis whose
/// leftover holds at least a tenth of the total, every shape of [`PatternKind`] against every
/// axis' motion, those removing at least [`MIN_EXPLAINED`] of the axis' leftover variance on
/// held-out folds, best first, at most [`MAX_PATTERNS`]. Periods come from the sinusoid search
/// of `best_period`; the shape at that period is a 16-bin table (a sawtooth or a spike train
/// is found as well as a sinusoid).
///
/// Formula: see `score`. Reference: blocked cross-validation (Roberts et al. 2017, "Cross-
/// validation strategies for data with temporal, spatial, hierarchical, or phylogenetic
/// structure", Ecography 40). Known bad cases: on a single pass, time, position and speed are
/// one and the same coordinate and the held-out folds cannot tell them apart (nothing is
/// reported); a jump is scored in-sample.
pub fn patterns(
    rest: &[Vec<f64>],
    cmd: &[Vec<f64>],
    pos: &[Vec<f64>],
    axes: &[String],
    period_s: f64,
) -> Vec<Pattern> {
    let dims = rest.len();
    let n = rest.first().map_or(0, Vec::len);
    if n < 10 * FOLDS {
        return Vec::new();
    }
    let centred: Vec<Vec<f64>> = rest
        .iter()
        .map(|r| {
            let m = r.iter().sum::<f64>() / n as f64;
            r.iter().map(|v| v - m).collect()
        })
        .collect();
    let vars: Vec<f64> = centred
        .iter()
        .map(|r| r.iter().map(|v| v * v).sum())
        .collect();
    let total: f64 = vars.iter().sum();
    let name = |k: usize| axes.get(k).cloned().unwrap_or_else(|| format!("axis {k}"));
    let mut out: Vec<(f64, Pattern)> = Vec::new();
    for k in 0..dims {
        if total <= 0.0 || vars[k] < 0.1 * total {
            continue;
        }
        let r = &centred[k];
        let mut found: Vec<Pattern> = Vec::new();
        let mut push = |kind,
                        of: Option<usize>,
                        (explained, h): (f64, Vec<f64>),
                        extra: &dyn Fn(&mut Pattern)| {
            let mut p = Pattern {
                kind,
                axis: name(k),
                of: of.map(name),
                explained,
                amplitude: half_range(&h),
                period_s: None,
                period_mm: None,
                event: None,
                at_s: None,
                description: String::new(),
            };
            extra(&mut p);
            found.push(p);
        };
        // periodic in time, any shape at the sinusoid's best period
        let t: Vec<f64> = (0..n).map(|i| i as f64 * period_s).collect();
        if let Some((p, _, _)) =
            best_period(&t, r, 10.0 * period_s, (n - 1) as f64 * period_s / 3.0)
        {
            let p = refine_period(&t, r, p);
            let shape = phase_shape(&t, p);
            push(PatternKind::PeriodicTime, None, score(r, &shape), &|q| {
                q.period_s = Some(p)
            });
        }
        for j in 0..dims {
            let x = &pos[j];
            let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &v| {
                (a.0.min(v), a.1.max(v))
            });
            if !(hi - lo).is_finite() || hi - lo <= 1e-3 {
                continue;
            }
            if let Some((p, _, _)) = best_period(x, r, 0.5, (hi - lo) / 1.5) {
                let p = refine_period(x, r, p);
                let shape = phase_shape(x, p);
                push(
                    PatternKind::PeriodicPosition,
                    Some(j),
                    score(r, &shape),
                    &|q| q.period_mm = Some(p),
                );
            }
            let position = Shape {
                groups: x.iter().map(|&v| bin(v, lo, hi)).collect(),
                signs: vec![1.0; n],
                count: BINS,
            };
            push(PatternKind::Position, Some(j), score(r, &position), &|_| {});
            let v = speed(&cmd[j]);
            let vmax = v.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            if vmax <= 0.0 {
                continue;
            }
            let speed_shape = Shape {
                groups: v.iter().map(|&s| bin(s, -vmax, vmax)).collect(),
                signs: vec![1.0; n],
                count: BINS,
            };
            push(PatternKind::Speed, Some(j), score(r, &speed_shape), &|_| {});
            let mut dir = v
                .iter()
                .find(|s| s.abs() > 0.01 * vmax)
                .map_or(1.0, |s| s.signum());
            let groups = v
                .iter()
                .map(|&s| {
                    if s.abs() > 0.01 * vmax {
                        dir = s.signum();
                    }
                    Some(usize::from(dir > 0.0))
                })
                .collect();
            let direction = Shape {
                groups,
                signs: vec![1.0; n],
                count: 2,
            };
            push(
                PatternKind::Direction,
                Some(j),
                score(r, &direction),
                &|_| {},
            );
            let events = axis_events(cmd, j, &name(j));
            for kind in ["reversal", "start", "stop"] {
                let at: Vec<usize> = events
                    .iter()
                    .filter(|(_, l)| l.ends_with(kind))
                    .map(|e| e.0)
                    .collect();
                if at.len() < 2 {
                    continue;
                }
                let shape = event_shape(&events, kind, &v, vmax, period_s, n);
                push(PatternKind::Event, Some(j), score(r, &shape), &|q| {
                    q.event = Some(kind.to_string())
                });
            }
        }
        if let Some((at, size, explained)) = best_jump(r) {
            push(
                PatternKind::Jump,
                None,
                (explained, vec![0.0, size]),
                &|q| q.at_s = Some(at as f64 * period_s),
            );
        }
        found.retain(|p| p.explained >= MIN_EXPLAINED);
        found.sort_by(|a, b| b.explained.total_cmp(&a.explained));
        found.truncate(3);
        for mut p in found {
            p.description = describe(&p);
            out.push((p.explained * vars[k] / total, p));
        }
    }
    out.sort_by(|a, b| b.0.total_cmp(&a.0));
    out.into_iter().take(MAX_PATTERNS).map(|p| p.1).collect()
}

/// The period near `p` (±1 %, steps of 0.05 %) at which the phase table of `r` against `u`
/// fits best in-sample: the sinusoid's period is slightly off for a sawtooth, and samples next
/// to its jump then fall into the wrong bin.
fn refine_period(u: &[f64], r: &[f64], p: f64) -> f64 {
    let rss = |q: f64| {
        let shape = phase_shape(u, q);
        let (mut num, mut den) = (vec![0.0; BINS], vec![0.0; BINS]);
        for (g, &v) in shape.groups.iter().zip(r) {
            let g = g.unwrap_or(0);
            num[g] += v;
            den[g] += 1.0;
        }
        shape
            .groups
            .iter()
            .zip(r)
            .map(|(g, &v)| {
                let g = g.unwrap_or(0);
                let m = if den[g] > 0.0 { num[g] / den[g] } else { 0.0 };
                (v - m) * (v - m)
            })
            .sum::<f64>()
    };
    (-20..=20)
        .map(|k| p * (1.0 + 0.0005 * k as f64))
        .map(|q| (q, rss(q)))
        .fold((p, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a })
        .0
}

/// Phase bins of coordinate `u` at period `p`.
fn phase_shape(u: &[f64], p: f64) -> Shape {
    Shape {
        groups: u
            .iter()
            .map(|&v| Some(((v / p).rem_euclid(1.0) * BINS as f64) as usize % BINS))
            .collect(),
        signs: vec![1.0; u.len()],
        count: BINS,
    }
}

/// Log-spaced bins of time since the last event of `kind` (within [`EVENT_WINDOW_S`] and
/// before the axis' next event), signed by the direction of the motion after the event (before
/// it for a stop).
fn event_shape(
    events: &[(usize, String)],
    kind: &str,
    v: &[f64],
    vmax: f64,
    period_s: f64,
    n: usize,
) -> Shape {
    let window = ((EVENT_WINDOW_S / period_s) as usize).max(EVENT_BINS);
    let mut groups = vec![None; n];
    let mut signs = vec![0.0; n];
    for (e, (at, label)) in events.iter().enumerate() {
        if !label.ends_with(kind) {
            continue;
        }
        let end = events.get(e + 1).map_or(n, |x| x.0).min(at + window).min(n);
        let moving = if kind == "stop" {
            (0..*at).rev().map(|i| v[i]).find(|s| s.abs() > 0.01 * vmax)
        } else {
            (*at..n).map(|i| v[i]).find(|s| s.abs() > 0.01 * vmax)
        };
        let sign = moving.map_or(1.0, f64::signum);
        for i in *at..end {
            let lag = (i - at + 1) as f64;
            let b = (lag.ln() / (window as f64).ln() * EVENT_BINS as f64) as usize;
            groups[i] = Some(b.min(EVENT_BINS - 1));
            signs[i] = sign;
        }
    }
    Shape {
        groups,
        signs,
        count: EVENT_BINS,
    }
}

/// One sentence for a pattern.
fn describe(p: &Pattern) -> String {
    let of = p.of.clone().unwrap_or_default();
    let pct = 100.0 * p.explained;
    let amp = p.amplitude * 1e3;
    match p.kind {
        PatternKind::PeriodicTime => format!(
            "{}'s leftover repeats every {:.3} s (±{amp:.1} µm; {pct:.0} % of it on held-out \
             data): a vibration, a resonance or a periodic disturbance",
            p.axis,
            p.period_s.unwrap_or(0.0)
        ),
        PatternKind::PeriodicPosition => format!(
            "{}'s leftover repeats every {:.2} mm of {of} (±{amp:.1} µm; {pct:.0} %): a screw, \
             an encoder or a rack periodic along {of}",
            p.axis,
            p.period_mm.unwrap_or(0.0)
        ),
        PatternKind::Event => format!(
            "{}'s leftover follows each {of} {} (±{amp:.1} µm; {pct:.0} %): stick-slip, a \
             resonance excited there, or a loose part that shifts",
            p.axis,
            p.event.as_deref().unwrap_or("event")
        ),
        PatternKind::Speed => format!(
            "{}'s leftover is a function of {of}'s speed (±{amp:.1} µm; {pct:.0} %): friction \
             that varies with speed, or a lag the servo model lacks",
            p.axis
        ),
        PatternKind::Direction => format!(
            "{}'s leftover follows {of}'s direction of motion (±{amp:.1} µm; {pct:.0} %): a \
             loose gib or a carriage that tilts with the direction",
            p.axis
        ),
        PatternKind::Position => format!(
            "{}'s leftover is a function of {of}'s position (±{amp:.1} µm; {pct:.0} %): a \
             geometric error along {of} (straightness, a bent screw, a kinematic parameter)",
            p.axis
        ),
        PatternKind::Jump => format!(
            "{}'s leftover jumps by {:.1} µm at {:.3} s ({pct:.0} %): lost counts or a sensor \
             fault, a knock, or a part that moved",
            p.axis,
            p.amplitude * 2e3,
            p.at_s.unwrap_or(0.0)
        ),
    }
}

#[cfg(test)]
mod tests;
