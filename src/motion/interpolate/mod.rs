//! Interpolator: program blocks → machine-axis command every interpolation period.
//!
//! Feed distribution (Zhang & Chen 2025 §2.2, eqs. 2–7): each block has a path parameter `s` whose
//! length is the tool-tip displacement `L_i` (eq. 2) when RTCP is on, else the extended
//! displacement `ΔL = √(ΔX²+ΔY²+ΔZ²+ΔA²+ΔC²)` with the rotary terms in radians (eq. 3). The
//! programmed F fixes the block time `T = L_i/F` (eq. 4; G93: `T = 1/F`), every axis moves
//! its own displacement in that same time (eq. 6: `F_x = ΔX/ΔL·F_s`, eq. 7), and RTCP maps
//! each interpolated tool-tip point through the inverse kinematics, so the machine axes
//! follow the non-linear path that keeps the tip on the programmed line.
//!
//! On top of the programmed feed: a jerk-limited S-curve along `s` ([`super::profile`]) whose
//! caps come from the per-axis `max_vel`, `max_accel`, `max_jerk` through the derivatives
//! `dq/ds`, `d²q/ds²`, `d³q/ds³` of the machine axes along the block (half of each axis'
//! acceleration/jerk budget goes to the tangential ramp, half to path curvature on curved
//! blocks), and a look-ahead over the whole program (backward and forward passes) so speed
//! carries through tangent junctions and drops at corners to the speed whose direction
//! change per period stays within `max_accel·period` on every axis. The direction change is
//! taken over the path the tool covers in one period around the junction, so a chain of
//! blocks shorter than that (a CAM post's chords of a small radius) counts all its turns
//! within the period: the speed through it is about `√(max_accel·R)`, the centripetal limit
//! of the radius `R` the chords approximate (`windowed_turn`).
//!
//! The program's path-control modes (exact stop, G64 P blending; [`PathControl`]) are applied
//! by `modes` and `blend` ([`interpolate_with`]), the machine's controller limits on dense
//! blocks (segment cap, block rate, look-ahead depth; [`Machine::controller`]) by
//! `controller`; without either the planning is the service's own, as above.
//!
//! Hand-written: no crate implements Zhang & Chen 2025's RTCP feed distribution, and the S-curve
//! planner must see the machine axes through the inverse kinematics.

use super::error::Error;
use super::gcode::{Block, Feed, Motion, Program};
use super::kinematics::Kinematics;
use super::machine::Machine;
use super::path_control::PathControl;
use chain::{over_caps, plan_units};

/// The interpolated command: one row per period.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    /// Interpolation period, s.
    pub period_s: f64,
    /// Sample times `k·period_s`, s.
    pub t: Vec<f64>,
    /// Machine-axis commands, one column per axis (X, Y, Z[, A, C]), mm / degrees.
    pub axes: Vec<Vec<f64>>,
    /// 1-based source line of the block being executed at each sample.
    pub line: Vec<u32>,
    /// The corners of the commanded path: block junctions where the tool-tip direction
    /// turns (tangent junctions are not listed). The samples straddle a corner at the
    /// junction speed, so the corner point itself is rarely a sample; the contour error
    /// needs it to measure against the programmed path rather than a chord across it.
    pub corners: Vec<Corner>,
}

/// A corner of the commanded path (see [`Trajectory::corners`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Corner {
    /// Index of the first sample taken at or after the junction time.
    pub before_sample: usize,
    /// Machine-axis position at the junction, X, Y, Z[, A, C] (mm, degrees).
    pub axes: Vec<f64>,
}

/// Smallest turn of the path direction at a block junction that is treated as a corner,
/// rad (0.05°): below it the junction is tangent for the contour-error spline.
const CORNER_RAD: f64 = 1e-3;

/// Angle (rad) between two direction vectors, 0 when either is zero.
fn turn_angle(a: &[f64; 5], b: &[f64; 5]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let na = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let nb = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    if na == 0.0 || nb == 0.0 {
        return 0.0;
    }
    (dot / (na * nb)).clamp(-1.0, 1.0).acos()
}

/// Default interpolation period (1 ms), s.
pub const DEFAULT_PERIOD_S: f64 = 1e-3;

struct Seg {
    len: f64,
    /// A straight machine-axis move (its direction is `d_in` = `d_out` all along).
    straight: bool,
    vcap: f64,
    acc: f64,
    jerk: f64,
    d_in: [f64; 5],
    d_out: [f64; 5],
}

fn axes_at(kin: &Kinematics, b: &Block, u: f64) -> [f64; 5] {
    let p = b.pose_at(u);
    if b.rtcp {
        kin.inverse(&p.xyz, p.a, p.c)
    } else {
        [p.xyz[0], p.xyz[1], p.xyz[2], p.a, p.c]
    }
}

fn is_machine_straight(b: &Block) -> bool {
    matches!(b.motion, Motion::Linear)
        && (!b.rtcp || (b.start.a == b.end.a && b.start.c == b.end.c))
}

/// Builds the planning segment of one motion block (length, caps, end tangents).
fn segment(kin: &Kinematics, m: &Machine, b: &Block, n_axes: usize) -> Seg {
    let da = (b.end.a - b.start.a).to_radians();
    let dc = (b.end.c - b.start.c).to_radians();
    let rot = (da * da + dc * dc).sqrt();
    let xyz = b.xyz_length();
    let len = if b.rtcp && xyz > 1e-9 {
        xyz
    } else {
        (xyz * xyz + rot * rot).sqrt()
    };
    let v_feed = match b.feed {
        Feed::Rapid => m.rapid_mm_min / 60.0,
        Feed::PerMinute(f) => f / 60.0,
        Feed::InverseTime(f) => len * f / 60.0,
    };
    let q0 = axes_at(kin, b, 0.0);
    let q1 = axes_at(kin, b, 1.0);
    let mut d1 = [0.0f64; 5];
    let mut d2 = [0.0f64; 5];
    let mut d3 = [0.0f64; 5];
    let (d_in, d_out);
    let straight = is_machine_straight(b);
    if straight {
        for i in 0..n_axes {
            d1[i] = ((q1[i] - q0[i]) / len).abs();
        }
        let dir: [f64; 5] = std::array::from_fn(|i| (q1[i] - q0[i]) / len);
        d_in = dir;
        d_out = dir;
    } else {
        let sweep = match b.motion {
            Motion::Arc { sweep_rad, .. } => sweep_rad.abs(),
            _ => 0.0,
        };
        let n = ((sweep / 5f64.to_radians()).ceil() as usize).clamp(24, 720);
        let h = 1.0 / n as f64;
        let q: Vec<[f64; 5]> = (0..=n).map(|k| axes_at(kin, b, k as f64 * h)).collect();
        let hs = h * len;
        for i in 0..n_axes {
            let f1: Vec<f64> = (0..n).map(|k| (q[k + 1][i] - q[k][i]) / hs).collect();
            let f2: Vec<f64> = (0..n - 1).map(|k| (f1[k + 1] - f1[k]) / hs).collect();
            let f3: Vec<f64> = (0..n - 2).map(|k| (f2[k + 1] - f2[k]) / hs).collect();
            d1[i] = f1.iter().fold(0.0, |a, v| a.max(v.abs()));
            d2[i] = f2.iter().fold(0.0, |a, v| a.max(v.abs()));
            d3[i] = f3.iter().fold(0.0, |a, v| a.max(v.abs()));
        }
        let eps = 1e-7;
        let qa = axes_at(kin, b, eps);
        let qb = axes_at(kin, b, 1.0 - eps);
        d_in = std::array::from_fn(|i| (qa[i] - q0[i]) / (eps * len));
        d_out = std::array::from_fn(|i| (q1[i] - qb[i]) / (eps * len));
    }
    let share = if straight { 1.0 } else { 0.5 };
    let (mut vcap, mut acc, mut jerk) = (v_feed, f64::INFINITY, f64::INFINITY);
    for (i, ax) in m.axes.iter().enumerate().take(n_axes) {
        let l = ax.limits;
        if d1[i] > 1e-12 {
            vcap = vcap.min(l.max_vel / d1[i]);
            acc = acc.min(share * l.max_accel / d1[i]);
            jerk = jerk.min(share * l.max_jerk / d1[i]);
        }
        if d2[i] > 1e-12 {
            vcap = vcap.min((0.5 * l.max_accel / d2[i]).sqrt());
        }
        if d3[i] > 1e-12 {
            vcap = vcap.min((0.5 * l.max_jerk / d3[i]).cbrt());
        }
    }
    Seg {
        len,
        straight,
        vcap,
        acc,
        jerk,
        d_in,
        d_out,
    }
}

/// Per-axis direction change (machine-axis units per mm of path, as `d_in`/`d_out`) across
/// junction `k` of `items` over the path within `half` mm on either side of it: the
/// direction `half` mm before against the direction `half` mm after, walking over straight
/// blocks shorter than the remaining distance. The walk stops at an arc (its own curvature
/// is capped in [`segment`]; its tangent at the end nearest the junction is taken), at a
/// dwell and at the ends of the program. With blocks longer than `half` on both sides this
/// is the change at the junction itself.
fn windowed_turn(items: &[(&Block, Option<Seg>)], k: usize, half: f64) -> [f64; 5] {
    let mut before = [0.0; 5];
    let (mut j, mut rem) = (k - 1, half);
    while let Some(s) = &items[j].1 {
        before = s.d_out;
        if s.len >= rem || !s.straight || j == 0 {
            break;
        }
        rem -= s.len;
        j -= 1;
    }
    let mut after = [0.0; 5];
    let (mut j, mut rem) = (k, half);
    while let Some(s) = items.get(j).and_then(|it| it.1.as_ref()) {
        after = s.d_in;
        if s.len >= rem || !s.straight {
            break;
        }
        rem -= s.len;
        j += 1;
    }
    std::array::from_fn(|i| (after[i] - before[i]).abs())
}

/// Interpolates `program` on `machine` every `period_s` seconds (machine at rest at the start
/// and at the end), every junction in the service's look-ahead: [`interpolate_with`] and no
/// path-control modes (the machine's controller limits still apply).
pub fn interpolate(
    program: &Program,
    machine: &Machine,
    period_s: f64,
    max_periods: usize,
) -> Result<Trajectory, Error> {
    interpolate_with(
        program,
        &PathControl::default(),
        machine,
        period_s,
        max_periods,
    )
}

/// Interpolates `program` on `machine` every `period_s` seconds (machine at rest at the start
/// and at the end), each block ending as `control` says (exact stop, G64 P blend, or the
/// look-ahead; `modes`) and within the machine's controller limits (`controller`). Fails
/// with [`Error::TooManyPeriods`] before allocating when the program needs more than
/// `max_periods` samples.
///
/// The first feed block after RTCP is switched on or off starts from where the machine
/// actually is (its position re-read in the new interpretation), as controllers do; an arc
/// there is rejected because its centre would refer to the other interpretation.
pub fn interpolate_with(
    program: &Program,
    control: &PathControl,
    machine: &Machine,
    period_s: f64,
    max_periods: usize,
) -> Result<Trajectory, Error> {
    if !(period_s.is_finite() && (1e-5..=0.1).contains(&period_s)) {
        return Err(Error::parameter(
            "period_s",
            format!("must be within 1e-5..0.1 s, got {period_s}"),
        ));
    }
    let kin = &machine.kinematics;
    let n_axes = kin.axis_count();
    if n_axes == 3 {
        for (line, axis) in [(program.first_a_line, 'A'), (program.first_c_line, 'C')] {
            if let Some(line) = line {
                return Err(Error::gcode(
                    line,
                    format!(
                        "axis {axis} is programmed but the machine (kinematics xyz) has no {axis} axis"
                    ),
                ));
            }
        }
    }
    // Re-base blocks whose start differs from the machine position (after RTCP toggles).
    let mut blocks: Vec<Block> = Vec::with_capacity(program.blocks.len());
    let mut q_cur = [0.0f64; 5];
    for b in &program.blocks {
        crate::numeric::stop::check();
        let mut b = b.clone();
        let q0 = axes_at(kin, &b, 0.0);
        if (0..n_axes).any(|i| (q0[i] - q_cur[i]).abs() > 1e-9) {
            if matches!(b.motion, Motion::Arc { .. }) {
                return Err(Error::gcode(
                    b.line,
                    "the first move after switching RTCP (G43.4/G49, TRAORI/TRAFOOF) must be G0 or G1, not an arc",
                ));
            }
            if b.rtcp {
                let tp = kin.forward(&q_cur);
                b.start.xyz = tp.tip;
            } else {
                b.start.xyz = [q_cur[0], q_cur[1], q_cur[2]];
            }
            b.start.a = q_cur[3];
            b.start.c = q_cur[4];
            if matches!(b.motion, Motion::Dwell { .. }) {
                b.end = b.start;
            }
        }
        q_cur = axes_at(kin, &b, 1.0);
        blocks.push(b);
    }
    let blocks = modes::blend_corners(blocks, control, machine);
    // Planning segments; dwells carry None, zero-length moves (possible after re-basing) go.
    let mut items: Vec<(&Block, Option<Seg>)> = Vec::with_capacity(blocks.len());
    for b in &blocks {
        crate::numeric::stop::check();
        if matches!(b.motion, Motion::Dwell { .. }) {
            items.push((b, None));
            continue;
        }
        let s = segment(kin, machine, b, n_axes);
        if s.len > 1e-12 {
            items.push((b, Some(s)));
        }
    }
    if !items.iter().any(|(_, s)| s.is_some()) {
        return Err(Error::EmptyProgram);
    }
    controller::cap_blocks(&mut items, &machine.controller, period_s);
    // Junction speeds: v[k] is the speed entering item k; v[n] = 0.
    let n = items.len();
    let mut v = vec![0.0f64; n + 1];
    for k in 1..n {
        let (Some(a), Some(b)) = (&items[k - 1].1, &items[k].1) else {
            continue;
        };
        // Largest speed v with v ≤ max_accel·period / (turn over the path of one period at
        // v), per axis: that turn grows with v, so the bound falls as v rises (bisection).
        let cap = |v: f64| -> f64 {
            let dd = windowed_turn(&items, k, 0.5 * v * period_s);
            let mut c = f64::INFINITY;
            for (i, ax) in machine.axes.iter().enumerate().take(n_axes) {
                if dd[i] > 1e-12 {
                    c = c.min(ax.limits.max_accel * period_s / dd[i]);
                }
            }
            c
        };
        let mut vj = a.vcap.min(b.vcap).min(cap(0.0));
        if cap(vj) < vj {
            let (mut lo, mut hi) = (cap(vj), vj);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if cap(mid) >= mid {
                    lo = mid;
                } else {
                    hi = mid;
                }
                if hi - lo <= 1e-9 * hi {
                    break;
                }
            }
            vj = lo;
        }
        v[k] = vj;
    }
    controller::cap_junctions(&items, &machine.controller, &mut v);
    modes::stop_junctions(&items, control, &mut v);
    // Planning units: chains of straight blocks joined where the junction does not slow the
    // tool below the blocks' speed caps are planned as one S-curve, so acceleration carries
    // across those junctions (as a controller's look-ahead does) instead of starting each
    // short block from zero acceleration (`chain_units`). A unit runs at its largest cap;
    // where that breaks a block's own cap or a junction's, the unit is split there and all
    // are planned again (at most a few rounds; after 20 every join of unequal caps goes).
    let mut split = vec![false; n + 1];
    let (mut units, mut pieces, mut t) = plan_units(&items, &v, &split);
    for round in 0.. {
        let over = over_caps(&items, &v, &units, &pieces);
        if over.is_empty() {
            break;
        }
        if round >= 20 {
            for k in 1..n {
                let caps = (items[k - 1].1.as_ref(), items[k].1.as_ref());
                if let (Some(a), Some(b)) = caps
                    && (a.vcap - b.vcap).abs() > 1e-9 * a.vcap.max(b.vcap)
                {
                    split[k] = true;
                }
            }
        }
        for k in over {
            split[k] = true;
        }
        (units, pieces, t) = plan_units(&items, &v, &split);
        if round >= 20 {
            break;
        }
    }
    let total = t;
    let periods = (total / period_s - 1e-9).ceil().max(0.0) as u64 + 1;
    if periods > max_periods as u64 {
        return Err(Error::TooManyPeriods {
            periods,
            limit: max_periods,
        });
    }
    let count = periods as usize;
    let mut out_t = Vec::with_capacity(count);
    let mut axes = vec![Vec::with_capacity(count); n_axes];
    let mut lines = Vec::with_capacity(count);
    // Corner junctions: between consecutive moves (a dwell between them is a stop, whose
    // junction is a corner as well when the direction turns).
    let mut corner_at: Vec<Option<Vec<f64>>> = vec![None; n];
    let mut prev: Option<&Seg> = None;
    for (k, (b, s)) in items.iter().enumerate() {
        if let Some(s) = s {
            if let Some(a) = prev
                && turn_angle(&a.d_out, &s.d_in) > CORNER_RAD
            {
                corner_at[k] = Some(axes_at(kin, b, 0.0)[..n_axes].to_vec());
            }
            prev = Some(s);
        }
    }
    let mut corners = Vec::new();
    let mut last_block = usize::MAX;
    let mut p = 0usize;
    for k in 0..count {
        let tk = k as f64 * period_s;
        while p + 1 < pieces.len() && tk >= pieces[p].t0 + pieces[p].dur {
            p += 1;
        }
        let piece = &pieces[p];
        let unit = &units[piece.block];
        let (item, u) = match &unit.seg {
            Some(_) if tk < total => unit.locate(&items, piece.s_at(tk)),
            _ => (unit.last, 1.0),
        };
        let b = items[item].0;
        if item != last_block {
            // Every block from the last one sampled up to this one starts before sample k.
            let from = if last_block == usize::MAX {
                0
            } else {
                last_block + 1
            };
            for c in corner_at.iter_mut().take(item + 1).skip(from) {
                if let Some(axes) = c.take() {
                    corners.push(Corner {
                        before_sample: k,
                        axes,
                    });
                }
            }
            last_block = item;
        }
        let q = axes_at(kin, b, u);
        for (i, col) in axes.iter_mut().enumerate() {
            col.push(q[i]);
        }
        out_t.push(tk);
        lines.push(b.line as u32);
    }
    Ok(Trajectory {
        period_s,
        t: out_t,
        axes,
        line: lines,
        corners,
    })
}

mod blend;
mod chain;
mod controller;
mod modes;
#[cfg(test)]
mod tests;
