//! The original programmed path as exact lines and arcs (not the interpolated samples), and
//! the foot of a tool-tip point on it: the contour error is measured against the drawing.

use super::MaterialSide;
use crate::motion::program::{Block, Feed, Motion, Plane, Program};
use crate::numeric::vec3::{add, dist, dot, norm, scale, sub};

/// Feet whose distances differ by less than this (mm) are ties, decided by continuity: the
/// one nearest along the path to the last foot. Overlapping geometry (a circle run twice, a
/// contour retraced) gives exact ties; 0.1 µm is the last printed digit.
pub const FOOT_TIE_MM: f64 = 1e-4;

/// How far ahead of the last foot (mm of path) the next foot is looked for. The tool tip
/// moves less than a millimetre a period at any feed a servo model allows, and a corner's
/// error is below a millimetre; 5 mm keeps a path that passes close to itself further on
/// (a zigzag, a spiral) from capturing the foot.
pub const SEARCH_AHEAD_MM: f64 = 5.0;

/// A block's geometry, machine frame, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Geom {
    /// Straight from `a` to `b`.
    Line {
        /// Start, mm.
        a: [f64; 3],
        /// End, mm.
        b: [f64; 3],
    },
    /// Circular or helical arc in `plane` about `centre` from `a`, sweep `sweep` rad (> 0
    /// counter-clockwise seen from the plane's normal), radius `radius` mm.
    Arc {
        /// Arc plane.
        plane: Plane,
        /// Start, mm.
        a: [f64; 3],
        /// End, mm.
        b: [f64; 3],
        /// Centre, mm (the plane's two components matter).
        centre: [f64; 3],
        /// Radius at the start, mm.
        radius: f64,
        /// Signed sweep, rad.
        sweep: f64,
    },
}

/// One block of the original program on the path.
#[derive(Clone, Debug)]
pub struct Segment {
    /// Its geometry.
    pub geom: Geom,
    /// Index of its block in the program.
    pub block: usize,
    /// Path length before it, mm.
    pub s0: f64,
    /// Its length, mm.
    pub len: f64,
    /// A cutting move (G1/G2/G3 at a feed) that the pre-distortion judges.
    pub cutting: bool,
    /// The material side where the program says it (G41/G42).
    pub side: Option<MaterialSide>,
}

/// The foot of a point on a segment.
#[derive(Clone, Copy, Debug)]
pub struct Foot {
    /// Path length to the foot, mm.
    pub s: f64,
    /// Distance, mm.
    pub dist: f64,
    /// Signed distance to the left of the direction of travel in the segment's plane, mm
    /// (XY for lines; 0 when the segment has no direction in that plane, e.g. a plunge).
    pub lateral: f64,
    /// Index of the segment.
    pub seg: usize,
}

impl Geom {
    /// The geometry of `block`; `None` for dwells.
    pub fn of(block: &Block) -> Option<Geom> {
        let (a, b) = (block.start.xyz, block.end.xyz);
        match block.motion {
            Motion::Linear => Some(Geom::Line { a, b }),
            Motion::Arc {
                plane,
                center,
                sweep_rad,
            } => {
                let (p0, p1, _) = plane.axes();
                Some(Geom::Arc {
                    plane,
                    a,
                    b,
                    centre: center,
                    radius: (a[p0] - center[p0]).hypot(a[p1] - center[p1]),
                    sweep: sweep_rad,
                })
            }
            Motion::Dwell { .. } => None,
        }
    }

    /// Length, mm.
    pub fn len(&self) -> f64 {
        match *self {
            Geom::Line { a, b } => dist(a, b),
            Geom::Arc {
                plane,
                a,
                b,
                radius,
                sweep,
                ..
            } => {
                let n = plane.axes().2;
                (radius * sweep).hypot(b[n] - a[n])
            }
        }
    }

    /// The point at fraction `t` ∈ [0, 1] of the block, mm.
    pub fn at(&self, t: f64) -> [f64; 3] {
        match *self {
            Geom::Line { a, b } => add(a, scale(sub(b, a), t)),
            Geom::Arc {
                plane,
                a,
                b,
                centre,
                radius,
                sweep,
            } => {
                let (p0, p1, n) = plane.axes();
                let a0 = (a[p1] - centre[p1]).atan2(a[p0] - centre[p0]);
                let ang = a0 + sweep * t;
                let mut q = [0.0; 3];
                q[p0] = centre[p0] + radius * ang.cos();
                q[p1] = centre[p1] + radius * ang.sin();
                q[n] = a[n] + (b[n] - a[n]) * t;
                q
            }
        }
    }

    /// Unit direction of travel at fraction `t`.
    pub fn tangent(&self, t: f64) -> [f64; 3] {
        match *self {
            Geom::Line { a, b } => {
                let d = sub(b, a);
                scale(d, 1.0 / norm(d).max(1e-300))
            }
            Geom::Arc {
                plane,
                a,
                b,
                centre,
                radius,
                sweep,
            } => {
                let (p0, p1, n) = plane.axes();
                let a0 = (a[p1] - centre[p1]).atan2(a[p0] - centre[p0]);
                let ang = a0 + sweep * t;
                let mut d = [0.0; 3];
                d[p0] = -radius * sweep * ang.sin();
                d[p1] = radius * sweep * ang.cos();
                d[n] = b[n] - a[n];
                scale(d, 1.0 / norm(d).max(1e-300))
            }
        }
    }

    /// The plane in which the lateral side is read: the arc's, XY for lines.
    pub fn plane(&self) -> Plane {
        match *self {
            Geom::Line { .. } => Plane::Xy,
            Geom::Arc { plane, .. } => plane,
        }
    }

    /// The fraction of the block nearest to `q`, and the distance, mm.
    pub fn nearest(&self, q: [f64; 3]) -> (f64, f64) {
        match *self {
            Geom::Line { a, b } => {
                let d = sub(b, a);
                let l2 = dot(d, d);
                let t = if l2 > 0.0 {
                    (dot(sub(q, a), d) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (t, dist(q, self.at(t)))
            }
            Geom::Arc {
                plane,
                a,
                centre,
                sweep,
                ..
            } => {
                let (p0, p1, _) = plane.axes();
                let a0 = (a[p1] - centre[p1]).atan2(a[p0] - centre[p0]);
                let aq = (q[p1] - centre[p1]).atan2(q[p0] - centre[p0]);
                // The angle from the start along the arc's own turning direction, in [0, 2π).
                let along = (sweep.signum() * (aq - a0)).rem_euclid(std::f64::consts::TAU);
                let t_in = along / sweep.abs().max(1e-300);
                let candidates = if t_in <= 1.0 {
                    vec![t_in]
                } else {
                    vec![0.0, 1.0]
                };
                candidates
                    .into_iter()
                    .map(|t| (t, dist(q, self.at(t))))
                    .fold((0.0, f64::INFINITY), |b, c| if c.1 < b.1 { c } else { b })
            }
        }
    }
}

/// The original path: its blocks as segments, in order.
#[derive(Clone, Debug)]
pub struct Path {
    /// Segments (dwells left out).
    pub segs: Vec<Segment>,
    /// Total length, mm.
    pub total: f64,
}

impl Path {
    /// The path of `program`; `cutting(block)` says which blocks are judged, `side(line)` the
    /// material side of a line where the program says it.
    pub fn new(
        program: &Program,
        keep: &dyn Fn(usize) -> bool,
        side: &dyn Fn(usize) -> Option<MaterialSide>,
    ) -> Path {
        let mut segs = Vec::new();
        let mut s0 = 0.0;
        for (i, b) in program.blocks.iter().enumerate() {
            let Some(geom) = Geom::of(b) else { continue };
            let len = geom.len();
            segs.push(Segment {
                geom,
                block: i,
                s0,
                len,
                cutting: b.feed != Feed::Rapid && !keep(b.line) && len > 0.0,
                side: side(b.line),
            });
            s0 += len;
        }
        Path { segs, total: s0 }
    }

    /// The foot of `q` on the path, searched from segment `from` (the last foot's, at path
    /// length `s_prev`) over the segments that start within [`SEARCH_AHEAD_MM`] of it (and
    /// the one before); ties within [`FOOT_TIE_MM`] go to the foot nearest to `s_prev`.
    pub fn foot(&self, q: [f64; 3], from: usize, s_prev: f64) -> Option<Foot> {
        let lo = from.saturating_sub(1);
        let limit = self.segs.get(from).map_or(0.0, |s| s.s0 + s.len) + SEARCH_AHEAD_MM;
        let mut cands: Vec<(usize, f64, f64)> = Vec::new();
        for (k, seg) in self.segs.iter().enumerate().skip(lo) {
            if k > from + 1 && seg.s0 > limit {
                break;
            }
            let (t, d) = seg.geom.nearest(q);
            cands.push((k, t, d));
        }
        let dmin = cands.iter().map(|c| c.2).fold(f64::INFINITY, f64::min);
        let &(k, t, d) = cands
            .iter()
            .filter(|c| c.2 <= dmin + FOOT_TIE_MM)
            .min_by(|a, b| {
                let sa = self.segs[a.0].s0 + a.1 * self.segs[a.0].len;
                let sb = self.segs[b.0].s0 + b.1 * self.segs[b.0].len;
                (sa - s_prev).abs().total_cmp(&(sb - s_prev).abs())
            })?;
        let seg = &self.segs[k];
        let tan = seg.geom.tangent(t);
        let (p0, p1, _) = seg.geom.plane().axes();
        let v = sub(q, seg.geom.at(t));
        let in_plane = tan[p0].hypot(tan[p1]);
        let lateral = if in_plane > 0.5 {
            (tan[p0] * v[p1] - tan[p1] * v[p0]) / in_plane
        } else {
            0.0
        };
        Some(Foot {
            s: seg.s0 + t * seg.len,
            dist: d,
            lateral,
            seg: k,
        })
    }
}

/// How far the point of a foot lies towards the material (mm, > 0 into it) and towards the
/// free side, for a segment's `side`: unknown side, both are the lateral's magnitude on its
/// side.
pub fn excursions(foot: &Foot, side: Option<MaterialSide>) -> (f64, f64) {
    let left = foot.lateral.max(0.0);
    let right = (-foot.lateral).max(0.0);
    match side {
        Some(MaterialSide::Left) => (left, right),
        Some(MaterialSide::Right) => (right, left),
        None => (foot.dist, 0.0),
    }
}
