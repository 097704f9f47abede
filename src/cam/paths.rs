//! Compensated paths of single blocks: the compensated path of a move x(t) is
//! c(t) = x(t) − e(x(t)). A straight block becomes straight pieces and an arc becomes
//! sub-arcs (never chords: a controller runs an arc as an arc, and chords multiply the blocks
//! and slow the tool on controllers that cap a segment's speed by its length), each within
//! the tolerance of c.
//!
//! Pieces are chosen greedily: from the start of the block, the longest piece that passes
//! its check (found by bisection on its end parameter), then on from there. For a check that
//! holds on every part of a piece that passes, greedy gives the fewest pieces; a check is
//! [`CHECKS`] interior samples of c against the piece (a smooth field's deviation from a
//! chord is a bump that these equally spaced samples see within a few per cent of its
//! peak, where the three samples of a quarter-piece check missed the midpoint of a 1.34 mm
//! semicircle by 1.13 µm).
//!
//! A sub-arc runs in the block's plane through the compensated ends of its piece, about the
//! centre on their perpendicular bisector nearest to the block's centre shifted by −e at the
//! piece's middle (so its start and end radii are equal, as controllers require), with the
//! normal axis moving linearly with the angle (a helix, as G2/G3 do).

use super::field::ErrorField;
use crate::motion::program::{Block, Plane};
use crate::numeric::vec3::{add, norm, scale, sub};

/// Interior samples of a piece compared with it (at k/(CHECKS + 1) of the piece).
pub const CHECKS: usize = 7;

/// Shortest piece, as a fraction of its block: 2⁻¹⁴ (at most 16,384 pieces a block), where a
/// field that is not smooth (a map's cell boundary) would otherwise split without end.
const MIN_PIECE: f64 = 1.0 / 16384.0;

/// Bisection steps of a piece's end parameter: the piece found is within 2⁻²⁰ of the
/// longest that passes, far below [`MIN_PIECE`].
const END_STEPS: usize = 20;

/// Evaluates the field, keeping the largest shift applied and the lines whose points fall
/// outside the field's box.
pub struct Shifter<'a> {
    field: &'a dyn ErrorField,
    /// Added to every compensated point, mm: the backlash offset b/2·d of the stretch being
    /// written (module `program`'s reversals; zero without backlash).
    pub bias: [f64; 3],
    /// Largest |e| applied to a written point, mm.
    pub max_shift_mm: f64,
    /// Lines with a point outside the field's box (each once, in order).
    pub out_of_box: Vec<usize>,
}

impl<'a> Shifter<'a> {
    /// A shifter on `field`.
    pub fn new(field: &'a dyn ErrorField) -> Self {
        Shifter {
            field,
            bias: [0.0; 3],
            max_shift_mm: 0.0,
            out_of_box: Vec::new(),
        }
    }

    /// e(p) − bias (mm) of a point written for `line`, recorded.
    pub fn error(&mut self, line: usize, p: [f64; 3]) -> [f64; 3] {
        let e = sub(self.field.error_at(p), self.bias);
        self.max_shift_mm = self.max_shift_mm.max(norm(e));
        if !self.field.contains(p) && self.out_of_box.last() != Some(&line) {
            self.out_of_box.push(line);
        }
        e
    }

    /// p − e(p) + bias (mm) of a point written for `line`, recorded.
    pub fn compensate(&mut self, line: usize, p: [f64; 3]) -> [f64; 3] {
        sub(p, self.error(line, p))
    }

    /// p − e(p) + bias (mm), not recorded (for checks).
    pub fn comp(&self, p: [f64; 3]) -> [f64; 3] {
        add(sub(p, self.field.error_at(p)), self.bias)
    }
}

/// Ends (parameters in (t0, t1], the last t1) of the greedy pieces of [t0, t1] under
/// `passes` (module docs), split first into `first_pieces` equal parts; `whole` asks for
/// those parts whatever the check says.
fn greedy(
    passes: &dyn Fn(f64, f64) -> bool,
    first_pieces: usize,
    (mut t0, t1): (f64, f64),
    whole: bool,
) -> Vec<f64> {
    let mut ends = Vec::new();
    // A block that must stay whole, or that is split at fixed points first (a full circle).
    let stops: Vec<f64> = (1..=first_pieces)
        .map(|k| {
            if k == first_pieces {
                t1
            } else {
                t0 + (t1 - t0) * k as f64 / first_pieces as f64
            }
        })
        .collect();
    for &stop in &stops {
        while t0 < stop {
            if whole || passes(t0, stop) {
                ends.push(stop);
                t0 = stop;
                continue;
            }
            let (mut ok, mut bad) = ((t0 + MIN_PIECE).min(stop), stop);
            if passes(t0, ok) {
                for _ in 0..END_STEPS {
                    let mid = 0.5 * (ok + bad);
                    if passes(t0, mid) {
                        ok = mid;
                    } else {
                        bad = mid;
                    }
                }
            }
            ends.push(ok);
            t0 = ok;
        }
    }
    ends
}

/// Compensated straight pieces (their ends, machine frame, mm; the last is the compensated
/// `end`) of the line from `start` to `end` (mm), each within `tol_mm` of c (module docs):
/// one piece when e is linear along the line within `tol_mm`, or when `whole`.
pub fn linear_points(
    sh: &mut Shifter<'_>,
    line: usize,
    start: [f64; 3],
    end: [f64; 3],
    tol_mm: f64,
    whole: bool,
) -> Vec<[f64; 3]> {
    let d = sub(end, start);
    let x = |t: f64| add(start, scale(d, t));
    let passes = |t0: f64, t1: f64| {
        let (c0, c1) = (sh.comp(x(t0)), sh.comp(x(t1)));
        (1..=CHECKS).all(|k| {
            let f = k as f64 / (CHECKS + 1) as f64;
            let chord = add(c0, scale(sub(c1, c0), f));
            norm(sub(sh.comp(x(t0 + (t1 - t0) * f)), chord)) <= tol_mm
        })
    };
    let ends = greedy(&passes, 1, (0.0, 1.0), whole);
    ends.iter()
        .map(|&t| sh.compensate(line, if t == 1.0 { end } else { x(t) }))
        .collect()
}

/// Parameters t in (0, 1) of the arc `block` (plane, centre, sweep; see [`arc_point`]) where
/// one of its plane's axes reverses (its extreme points: the angle a multiple of π for the
/// first axis, of π/2 but not π for the second), in order.
pub fn arc_reversals(plane: Plane, block: &Block, center: [f64; 3], sweep_rad: f64) -> Vec<f64> {
    let (p0, p1, _) = plane.axes();
    let s = block.start.xyz;
    let a0 = (s[p1] - center[p1]).atan2(s[p0] - center[p0]);
    let half = std::f64::consts::FRAC_PI_2;
    let (lo, hi) = if sweep_rad >= 0.0 {
        (a0, a0 + sweep_rad)
    } else {
        (a0 + sweep_rad, a0)
    };
    let mut out: Vec<f64> = ((lo / half).floor() as i64..=(hi / half).ceil() as i64)
        .map(|k| (k as f64 * half - a0) / sweep_rad)
        .filter(|t| *t > 1e-9 && *t < 1.0 - 1e-9)
        .collect();
    out.sort_by(f64::total_cmp);
    out
}

/// Direction (−1, 0, +1) of each axis (X, Y, Z) along the arc `block` between parameters
/// `t0` and `t1`, where no axis reverses ([`arc_reversals`]): the sign of its velocity at
/// the middle; along the normal axis, of the helix' rise.
pub fn arc_directions(
    plane: Plane,
    block: &Block,
    center: [f64; 3],
    sweep_rad: f64,
    (t0, t1): (f64, f64),
) -> [f64; 3] {
    let (p0, p1, n) = plane.axes();
    let s = block.start.xyz;
    let a = (s[p1] - center[p1]).atan2(s[p0] - center[p0]) + sweep_rad * 0.5 * (t0 + t1);
    let sign = |v: f64| if v.abs() < 1e-12 { 0.0 } else { v.signum() };
    let mut d = [0.0; 3];
    d[p0] = sign(-a.sin() * sweep_rad);
    d[p1] = sign(a.cos() * sweep_rad);
    d[n] = sign(block.end.xyz[n] - s[n]);
    d
}

/// A point of the arc `block` (plane, centre, sweep) at parameter t in [0, 1]: the angle and
/// the radius (start to end) and the helix axis vary linearly.
pub fn arc_point(
    block: &Block,
    plane: Plane,
    center: [f64; 3],
    sweep_rad: f64,
    t: f64,
) -> [f64; 3] {
    let (p0, p1, n) = plane.axes();
    let s = block.start.xyz;
    let e = block.end.xyz;
    let r0 = (s[p0] - center[p0]).hypot(s[p1] - center[p1]);
    let r1 = (e[p0] - center[p0]).hypot(e[p1] - center[p1]);
    let a0 = (s[p1] - center[p1]).atan2(s[p0] - center[p0]);
    let a = a0 + sweep_rad * t;
    let r = r0 + (r1 - r0) * t;
    let mut p = [0.0; 3];
    p[p0] = center[p0] + r * a.cos();
    p[p1] = center[p1] + r * a.sin();
    p[n] = s[n] + (e[n] - s[n]) * t;
    if t == 1.0 {
        return e;
    }
    p
}

/// One sub-arc of a compensated arc: its end and centre (machine frame, mm; the centre's
/// normal-axis component is the end's) in the block's plane and turning direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubArc {
    /// End point, machine frame, mm.
    pub end_mm: [f64; 3],
    /// Centre, machine frame, mm.
    pub centre_mm: [f64; 3],
    /// Sweep, rad (positive counter-clockwise seen from the plane's normal).
    pub sweep_rad: f64,
}

/// The sub-arc from `a` to `b` (mm) in `plane`, of about `sweep` rad, about the point of the
/// perpendicular bisector of `ab` nearest to `hint` (mm); `None` when `a` and `b` coincide
/// in the plane.
pub fn sub_arc(
    plane: Plane,
    a: [f64; 3],
    b: [f64; 3],
    hint: [f64; 3],
    sweep: f64,
) -> Option<SubArc> {
    let (p0, p1, _) = plane.axes();
    let mid = [0.5 * (a[p0] + b[p0]), 0.5 * (a[p1] + b[p1])];
    let chord = [b[p0] - a[p0], b[p1] - a[p1]];
    let len = chord[0].hypot(chord[1]);
    if len < 1e-12 {
        return None;
    }
    // Unit normal of the chord in the plane; the centre is mid + s·normal.
    let nrm = [-chord[1] / len, chord[0] / len];
    let s = (hint[p0] - mid[0]) * nrm[0] + (hint[p1] - mid[1]) * nrm[1];
    let mut centre = b;
    centre[p0] = mid[0] + s * nrm[0];
    centre[p1] = mid[1] + s * nrm[1];
    let ang = |q: [f64; 3]| (q[p1] - centre[p1]).atan2(q[p0] - centre[p0]);
    let raw = ang(b) - ang(a);
    let turns = ((sweep - raw) / std::f64::consts::TAU).round();
    Some(SubArc {
        end_mm: b,
        centre_mm: centre,
        sweep_rad: raw + turns * std::f64::consts::TAU,
    })
}

/// Distance (mm) of `q` from the sub-arc `arc` that starts at `a`: in the plane, from its
/// circle; along the normal axis, from the helix at `q`'s angle.
fn off_sub_arc(plane: Plane, a: [f64; 3], arc: &SubArc, q: [f64; 3]) -> f64 {
    let (p0, p1, n) = plane.axes();
    let c = arc.centre_mm;
    let rho = (a[p0] - c[p0]).hypot(a[p1] - c[p1]);
    let radial = (q[p0] - c[p0]).hypot(q[p1] - c[p1]) - rho;
    let a0 = (a[p1] - c[p1]).atan2(a[p0] - c[p0]);
    let aq = (q[p1] - c[p1]).atan2(q[p0] - c[p0]);
    let mut d = aq - a0;
    // The angle of q along the sub-arc's own turning direction, in [0, |sweep|] when on it.
    if arc.sweep_rad < 0.0 {
        d = -d;
    }
    let d = d.rem_euclid(std::f64::consts::TAU);
    let frac = if arc.sweep_rad != 0.0 {
        (d / arc.sweep_rad.abs()).min(1.0)
    } else {
        0.0
    };
    let helix = a[n] + (arc.end_mm[n] - a[n]) * frac;
    radial.hypot(q[n] - helix)
}

/// The compensated arc `block` from parameter `range.0` to `range.1` (the whole arc: 0 to 1)
/// as sub-arcs (module docs), each within `tol_mm` of c; one sub-arc when e is constant (or
/// linear enough) along it, or when `whole` (a full circle: two).
#[allow(clippy::too_many_arguments)]
pub fn arc_pieces(
    sh: &mut Shifter<'_>,
    line: usize,
    block: &Block,
    plane: Plane,
    center: [f64; 3],
    sweep_rad: f64,
    tol_mm: f64,
    whole: bool,
    range: (f64, f64),
) -> Vec<SubArc> {
    let x = |t: f64| arc_point(block, plane, center, sweep_rad, t);
    let fit = |t0: f64, t1: f64| {
        let (c0, c1) = (sh.comp(x(t0)), sh.comp(x(t1)));
        let hint = add(sub(center, sh.field.error_at(x(0.5 * (t0 + t1)))), sh.bias);
        sub_arc(plane, c0, c1, hint, sweep_rad * (t1 - t0)).map(|a| (c0, a))
    };
    let passes = |t0: f64, t1: f64| match fit(t0, t1) {
        Some((c0, arc)) => (1..=CHECKS).all(|k| {
            let f = k as f64 / (CHECKS + 1) as f64;
            off_sub_arc(plane, c0, &arc, sh.comp(x(t0 + (t1 - t0) * f))) <= tol_mm
        }),
        None => false,
    };
    // A piece of less than a full turn has one reading from its ends, centre and direction;
    // a full circle (or more) starts as equal pieces of less than a turn.
    let part = sweep_rad.abs() * (range.1 - range.0);
    let first = (part / std::f64::consts::TAU + 1e-9).floor() as usize + 1;
    let ends = greedy(&passes, first, range, whole);
    let mut out = Vec::with_capacity(ends.len());
    let mut t0 = range.0;
    for &t1 in &ends {
        let end = sh.compensate(line, if t1 == 1.0 { block.end.xyz } else { x(t1) });
        let start = sh.comp(x(t0));
        let hint = add(sub(center, sh.field.error_at(x(0.5 * (t0 + t1)))), sh.bias);
        let arc = sub_arc(plane, start, end, hint, sweep_rad * (t1 - t0)).unwrap_or(SubArc {
            end_mm: end,
            centre_mm: hint,
            sweep_rad: sweep_rad * (t1 - t0),
        });
        out.push(arc);
        t0 = t1;
    }
    out
}
