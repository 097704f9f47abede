//! Compensated paths of single blocks: the compensated path of a move x(t) is
//! c(t) = x(t) − e(x(t)); a G1 polyline through points of c follows it within the tolerance
//! when each piece's chord stays within the tolerance of c at a quarter, half and three
//! quarters of the piece (bisection until it does). Arcs whose e is constant within the
//! tolerance stay arcs shifted by the mean error.
//!
//! The sagitta of a piece of circle is largest at its middle, and the pieces of an arc start
//! at most 22.5° long, so three checks per piece see the chord error; the variation of a
//! smooth e over a short piece is dominated by its curvature there, which the same checks see.

use super::field::ErrorField;
use crate::motion::program::{Block, Plane};
use crate::numeric::vec3::{add, norm, scale, sub};

/// Deepest bisection of one piece (at most 2^14 points per piece).
const MAX_DEPTH: usize = 14;

/// Evaluates the field, keeping the largest shift applied and the lines whose points fall
/// outside the field's box.
pub struct Shifter<'a> {
    field: &'a dyn ErrorField,
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
            max_shift_mm: 0.0,
            out_of_box: Vec::new(),
        }
    }

    /// e(p) (mm) of a point written for `line`, recorded.
    pub fn error(&mut self, line: usize, p: [f64; 3]) -> [f64; 3] {
        let e = self.field.error_at(p);
        self.max_shift_mm = self.max_shift_mm.max(norm(e));
        if !self.field.contains(p) && self.out_of_box.last() != Some(&line) {
            self.out_of_box.push(line);
        }
        e
    }

    /// p − e(p) (mm) of a point written for `line`, recorded.
    pub fn compensate(&mut self, line: usize, p: [f64; 3]) -> [f64; 3] {
        sub(p, self.error(line, p))
    }

    /// p − e(p) (mm), not recorded (for checks).
    pub fn comp(&self, p: [f64; 3]) -> [f64; 3] {
        sub(p, self.field.error_at(p))
    }
}

/// Compensated G1 points (machine frame, mm; the last is the compensated end) of the line
/// from `start` to `end` (mm): one point when e is linear along it within `tol_mm`.
pub fn linear_points(
    sh: &mut Shifter<'_>,
    line: usize,
    start: [f64; 3],
    end: [f64; 3],
    tol_mm: f64,
) -> Vec<[f64; 3]> {
    let d = sub(end, start);
    let x = |t: f64| add(start, scale(d, t));
    let c0 = sh.comp(start);
    let c1 = sh.comp(end);
    let mut out = Vec::new();
    piece(sh, &x, (0.0, c0), (1.0, c1), tol_mm, 0, &mut out);
    written(sh, line, &x, out, end)
}

/// The written points of the accepted pieces, recording their shifts; the last is the
/// compensated `end`.
fn written(
    sh: &mut Shifter<'_>,
    line: usize,
    x: &dyn Fn(f64) -> [f64; 3],
    out: Vec<(f64, [f64; 3])>,
    end: [f64; 3],
) -> Vec<[f64; 3]> {
    let n = out.len();
    out.into_iter()
        .enumerate()
        .map(|(i, (t, _))| {
            let p = if i + 1 == n { end } else { x(t) };
            sh.compensate(line, p)
        })
        .collect()
}

/// Bisection of the piece (t0, c0)–(t1, c1) of the path `x` until its chord is within
/// `tol` of the compensated path; pushes the end of every accepted piece.
fn piece(
    sh: &Shifter<'_>,
    x: &dyn Fn(f64) -> [f64; 3],
    (t0, c0): (f64, [f64; 3]),
    (t1, c1): (f64, [f64; 3]),
    tol: f64,
    depth: usize,
    out: &mut Vec<(f64, [f64; 3])>,
) {
    let mut mid = c0;
    let mut ok = true;
    for f in [0.5, 0.25, 0.75] {
        let c = sh.comp(x(t0 + (t1 - t0) * f));
        if f == 0.5 {
            mid = c;
        }
        let chord = add(c0, scale(sub(c1, c0), f));
        if norm(sub(c, chord)) > tol {
            ok = false;
            break;
        }
    }
    if ok || depth >= MAX_DEPTH {
        out.push((t1, c1));
        return;
    }
    let tm = 0.5 * (t0 + t1);
    piece(sh, x, (t0, c0), (tm, mid), tol, depth + 1, out);
    piece(sh, x, (tm, mid), (t1, c1), tol, depth + 1, out);
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

/// A compensated arc: kept and shifted, or G1 points.
#[derive(Clone, Debug, PartialEq)]
pub enum CompensatedArc {
    /// e is constant along the arc within the tolerance: the arc shifted by the mean of e
    /// at its ends.
    Shifted {
        /// End point, machine frame, mm.
        end_mm: [f64; 3],
        /// Centre, machine frame, mm.
        centre_mm: [f64; 3],
    },
    /// G1 points (machine frame, mm) within the tolerance of the compensated arc.
    Points(Vec<[f64; 3]>),
}

/// The compensated arc `block`: [`CompensatedArc::Shifted`] when e is constant along it within
/// `tol_mm`, else [`CompensatedArc::Points`] within `tol_mm` of the compensated arc (pieces of
/// at most 22.5°, bisected).
pub fn arc_points(
    sh: &mut Shifter<'_>,
    line: usize,
    block: &Block,
    plane: Plane,
    center: [f64; 3],
    sweep_rad: f64,
    tol_mm: f64,
) -> CompensatedArc {
    let x = |t: f64| arc_point(block, plane, center, sweep_rad, t);
    let e0 = sh.field.error_at(block.start.xyz);
    let e1 = sh.field.error_at(block.end.xyz);
    let mean = scale(add(e0, e1), 0.5);
    let samples = ((sweep_rad.abs() / (std::f64::consts::PI / 16.0)).ceil() as usize).max(8);
    let constant = (0..=samples).all(|i| {
        let e = sh.field.error_at(x(i as f64 / samples as f64));
        norm(sub(e, mean)) <= tol_mm
    });
    if constant {
        let end = sh.compensate(line, block.end.xyz);
        return CompensatedArc::Shifted {
            end_mm: end,
            centre_mm: sub(center, mean),
        };
    }
    let pieces = ((sweep_rad.abs() / (std::f64::consts::PI / 8.0)).ceil() as usize).max(1);
    let mut out = Vec::new();
    let mut prev = (0.0, sh.comp(block.start.xyz));
    for j in 1..=pieces {
        let t = j as f64 / pieces as f64;
        let next = (t, sh.comp(x(t)));
        piece(sh, &x, prev, next, tol_mm, 0, &mut out);
        prev = next;
    }
    CompensatedArc::Points(written(sh, line, &x, out, block.end.xyz))
}
