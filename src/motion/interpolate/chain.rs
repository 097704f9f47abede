//! Planning units of the interpolator's look-ahead: chains of straight blocks whose
//! junctions do not slow the tool, planned as one S-curve so the acceleration carries across
//! them (a controller's look-ahead over short blocks), and the check that splits a chain
//! where its plan would break a block's own feed or a junction's direction-change limit.

use super::Seg;
use crate::motion::gcode::{Block, Motion};
use crate::motion::profile::{self, Piece};

/// Consecutive planning items run as one S-curve ([`chain_units`]).
pub(super) struct Unit {
    /// First and last item index (inclusive).
    pub first: usize,
    pub last: usize,
    /// The merged segment: summed length, the largest speed cap of its blocks (a block of
    /// lower cap is checked by [`over_caps`]), their smallest acceleration and jerk caps.
    /// `None` for a dwell.
    pub seg: Option<Seg>,
    /// Path length (mm) from the unit's start to the start of each of its items.
    pub starts: Vec<f64>,
}

impl Unit {
    /// The item and its own parameter `u` ∈ [0, 1] at `s` mm along the unit.
    pub(super) fn locate(&self, items: &[(&Block, Option<Seg>)], s: f64) -> (usize, f64) {
        let i = self
            .starts
            .partition_point(|c| *c <= s)
            .clamp(1, self.starts.len())
            - 1;
        let k = self.first + i;
        let len = items[k].1.as_ref().map_or(0.0, |g| g.len);
        let u = if len > 0.0 {
            ((s - self.starts[i]) / len).clamp(0.0, 1.0)
        } else {
            1.0
        };
        (k, u)
    }
}

/// Groups `items` into planning units. Junction `k` (between items `k − 1` and `k`) joins
/// one unit unless `split[k]`, when both blocks are straight machine-axis moves and the
/// junction's own cap `v[k]` (the direction-change rule) is at least the lower of the two
/// blocks' speed caps: the junction does not slow the tool, so a controller's look-ahead
/// runs through it without restarting its acceleration ramp. A straight line split into
/// collinear pieces then plans exactly as the unsplit line, and a CAM post's chords of a
/// large radius as one smooth run. The unit's speed cap is the largest of its blocks' (the
/// caller splits where the plan breaks a lower one, [`over_caps`]); its acceleration and
/// jerk caps are the smallest of its blocks' (each block's share of the axis limits along
/// its own direction), so no axis limit is exceeded on any of them; the direction change at
/// the junctions stays within `max_accel·period` per axis by the junction rule.
fn chain_units(items: &[(&Block, Option<Seg>)], v: &[f64], split: &[bool]) -> Vec<Unit> {
    let joins = |k: usize| -> bool {
        let (Some(a), Some(b)) = (&items[k - 1].1, &items[k].1) else {
            return false;
        };
        !split[k] && a.straight && b.straight && v[k] >= a.vcap.min(b.vcap)
    };
    let mut units: Vec<Unit> = Vec::with_capacity(items.len());
    for (k, (_, s)) in items.iter().enumerate() {
        if k > 0 && joins(k) {
            let u = units.last_mut().expect("a unit before a join");
            let seg = u.seg.as_mut().expect("joined units are moves");
            let s = s.as_ref().expect("joined items are moves");
            u.starts.push(seg.len);
            u.last = k;
            seg.len += s.len;
            seg.acc = seg.acc.min(s.acc);
            seg.jerk = seg.jerk.min(s.jerk);
            seg.vcap = seg.vcap.max(s.vcap);
            seg.d_out = s.d_out;
            continue;
        }
        units.push(Unit {
            first: k,
            last: k,
            seg: s.as_ref().map(|s| Seg {
                len: s.len,
                straight: s.straight,
                vcap: s.vcap,
                acc: s.acc,
                jerk: s.jerk,
                d_in: s.d_in,
                d_out: s.d_out,
            }),
            starts: vec![0.0],
        });
    }
    units
}

/// Plans `items` with junction caps `v` (the direction-change rule; `v[n]` = 0) in the
/// planning units of [`chain_units`] (`split[k]`: junction `k` may not join a unit):
/// look-ahead passes over the units, then one S-curve per unit. Returns the units, their
/// pieces (each piece's `block` is its unit's index) and the end time (s).
pub(super) fn plan_units(
    items: &[(&Block, Option<Seg>)],
    v: &[f64],
    split: &[bool],
) -> (Vec<Unit>, Vec<Piece>, f64) {
    // Planning units: chains of straight blocks joined where the junction does not slow the
    // tool below the blocks' common speed cap are planned as one S-curve, so acceleration
    // carries across those junctions (as a controller's look-ahead does) instead of starting
    // each short block from zero acceleration (`chain_units`).
    let units = chain_units(items, v, split);
    let nu = units.len();
    let mut vu: Vec<f64> = units.iter().map(|u| v[u.first]).collect();
    vu.push(0.0);
    // Backward pass (must be able to slow down to the next junction), then forward pass.
    for k in (0..nu).rev() {
        if let Some(s) = &units[k].seg
            && vu[k] > vu[k + 1]
            && profile::ramp_distance(vu[k + 1], vu[k], s.acc, s.jerk) > s.len
        {
            vu[k] = profile::max_reachable_speed(vu[k + 1], s.len, s.acc, s.jerk).min(vu[k]);
        }
    }
    for k in 0..nu {
        if let Some(s) = &units[k].seg
            && vu[k + 1] > vu[k]
            && profile::ramp_distance(vu[k], vu[k + 1], s.acc, s.jerk) > s.len
        {
            vu[k + 1] = profile::max_reachable_speed(vu[k], s.len, s.acc, s.jerk).min(vu[k + 1]);
        }
    }
    // Pieces (their `block` is the unit's index).
    let mut pieces: Vec<Piece> = Vec::with_capacity(4 * nu);
    let mut t = 0.0;
    for (k, unit) in units.iter().enumerate() {
        match &unit.seg {
            Some(s) => {
                let lim = profile::BlockLimits {
                    len: s.len,
                    v0: vu[k],
                    v1: vu[k + 1],
                    vcap: s.vcap,
                    a: s.acc,
                    j: s.jerk,
                };
                t = profile::plan_block(&mut pieces, k, t, lim);
            }
            None => {
                let Motion::Dwell { seconds } = items[unit.first].0.motion else {
                    continue;
                };
                pieces.push(Piece {
                    t0: t,
                    dur: seconds,
                    s0: 0.0,
                    v0: 0.0,
                    a0: 0.0,
                    j: 0.0,
                    block: k,
                });
                t += seconds;
            }
        }
    }
    (units, pieces, t)
}

/// Junctions inside `units` where the planned speed breaks a limit of the blocks it joins:
/// the speed at the junction above its direction-change cap `v[k]`, or the speed anywhere
/// on a block above that block's own speed cap (a unit runs at its largest cap; blocks of
/// lower cap are checked here). Each junction returned must end a unit: both ends of the
/// run of equal-cap blocks around an offending block, or the offending junction.
pub(super) fn over_caps(
    items: &[(&Block, Option<Seg>)],
    v: &[f64],
    units: &[Unit],
    pieces: &[Piece],
) -> Vec<usize> {
    let mut out = Vec::new();
    let mut p0 = 0usize;
    for (u, unit) in units.iter().enumerate() {
        let p1 = pieces[p0..].partition_point(|p| p.block == u) + p0;
        let mine = &pieces[p0..p1];
        p0 = p1;
        if unit.first == unit.last || mine.is_empty() {
            continue;
        }
        let caps: Vec<f64> = (unit.first..=unit.last)
            .map(|k| items[k].1.as_ref().map_or(0.0, |g| g.vcap))
            .collect();
        let top = caps.iter().fold(0.0f64, |m, c| m.max(*c));
        if caps.iter().all(|c| *c >= top * (1.0 - 1e-12)) {
            // Uniform caps: the S-curve keeps to the cap; the join rule keeps the junctions.
            continue;
        }
        // The profile rises, cruises, falls: its peak speed and where it is held.
        let ends: Vec<(f64, f64)> = mine
            .iter()
            .map(|p| {
                let t = p.dur;
                (p.s_at(p.t0 + t), p.v0 + t * (p.a0 + 0.5 * p.j * t))
            })
            .collect();
        let mut peak = (mine[0].v0, mine[0].s0, mine[0].s0);
        for (p, (s1, v1)) in mine.iter().zip(&ends) {
            for (s, sp) in [(p.s0, p.v0), (*s1, *v1)] {
                if sp > peak.0 * (1.0 + 1e-12) {
                    peak = (sp, s, s);
                } else if sp >= peak.0 * (1.0 - 1e-12) {
                    peak.2 = s;
                }
            }
        }
        let speed_at = |s: f64| -> f64 {
            let i = mine.partition_point(|p| p.s0 <= s).clamp(1, mine.len()) - 1;
            let p = &mine[i];
            let (mut lo, mut hi) = (0.0, p.dur);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if p.s_at(p.t0 + mid) < s {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let t = 0.5 * (lo + hi);
            p.v0 + t * (p.a0 + 0.5 * p.j * t)
        };
        for (i, k) in (unit.first..=unit.last).enumerate() {
            let sa = unit.starts[i];
            let sb = unit.starts.get(i + 1).copied().unwrap_or(f64::INFINITY);
            let top_here = if sb >= peak.1 && sa <= peak.2 {
                peak.0
            } else {
                speed_at(sa).max(speed_at(sb.min(ends.last().map_or(sa, |e| e.0))))
            };
            if top_here > caps[i] * (1.0 + 1e-9) {
                // Split around the run of blocks with this block's cap.
                let same = |j: usize| (caps[j] - caps[i]).abs() <= 1e-9 * caps[i];
                let (mut i0, mut i1) = (i, i);
                while i0 > 0 && same(i0 - 1) {
                    i0 -= 1;
                }
                while i1 + 1 < caps.len() && same(i1 + 1) {
                    i1 += 1;
                }
                out.push(unit.first + i0);
                out.push(unit.first + i1 + 1);
            } else if i > 0 && speed_at(sa) > v[k] * (1.0 + 1e-9) {
                out.push(k);
            }
        }
    }
    out
}
