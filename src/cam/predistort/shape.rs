//! What the pre-distortion may change, as a few parameters per feature of the path
//! (module docs of [`super`]), and the program those parameters write.
//!
//! - A **corner** (a junction of two cutting blocks that turns by at least
//!   [`CORNER_MIN_RAD`]) has four: the corner point's offset `δ1` along the outward bisector
//!   and `δ2` along the mean direction of travel (mm; both 0 where the two blocks do not lie
//!   in one XY level, so that no Z word is written on a 2-D cut and none moves a floor), and
//!   a stretch of length `L` (mm) on each side of the corner run at the fraction `f` of the
//!   block's feed. The blocks on each side gain one point each (where the slow stretch
//!   begins or ends): at most three pieces per block.
//! - An **arc** in G17 has one: `ΔR` (mm), the change of its radius. The arc is written as
//!   three sub-arcs: one into the circle of radius R + ΔR, one on it about the original
//!   centre, one out of it (each a true circle through its ends, so start and end radii
//!   agree as controllers require). Arcs in G18/G19 keep their radius: there a larger
//!   radius would move the arc's lowest point below the floor.
//!
//! Feeds are only lowered (`f` ≤ 1): no piece runs faster than its source block's F.

use super::path::{Geom, Path};
use crate::cam::paths::sub_arc;
use crate::motion::Machine;
use crate::motion::program::{Block, Feed, Motion, Plane, Pose, Program};
use crate::numeric::vec3::{add, dot, norm, scale, sub};

/// Smallest turn of a junction that is a corner feature, rad (5°): below it the junction is
/// a point of a smooth curve that CAM chorded (a 0.25 mm chord of a 3 mm radius turns
/// 4.8°), whose error is the servo's radius loss along the curve rather than a corner's.
pub const CORNER_MIN_RAD: f64 = 0.087;

/// Lowest feed fraction of a slowed stretch: 5 % of F. Below it a stretch of a millimetre
/// takes seconds and the duration gate, not the error, decides.
pub const MIN_FEED_FRACTION: f64 = 0.05;

/// The feed fraction a corner starts from: slightly slowed, so that the first derivative
/// of the error with respect to the stretch length is not zero (at f = 1 the length does
/// nothing).
pub const START_FEED_FRACTION: f64 = 0.9;

/// Length of an arc's transition into its new radius and the start length of a slowed
/// stretch, in servo time constants (1/kv) of travel at the block's feed: the servo
/// follows a change of direction within about two time constants.
pub const TRANSITION_TIME_CONSTANTS: f64 = 2.0;

/// The largest share of a block's length one feature's pieces may take (45 %): the two
/// ends of a block never overlap, and a middle piece always remains.
pub const MAX_LENGTH_SHARE: f64 = 0.45;

/// The corner point may move up to this multiple of the largest error the original shows
/// near it (the servo's lag cuts a corner by about that much; a reach of twice that lets
/// the search overshoot and come back).
pub const REACH_FACTOR: f64 = 2.0;

/// One piece of a rewritten block (machine frame, mm; feed mm/min).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Piece {
    /// G1 to `end`.
    Line {
        /// End point, mm.
        end: [f64; 3],
        /// Feed, mm/min.
        feed_mm_min: f64,
    },
    /// G2/G3 to `end` about `centre` in `plane`, sweep `sweep_rad` (> 0 counter-clockwise).
    Arc {
        /// End point, mm.
        end: [f64; 3],
        /// Centre, mm.
        centre: [f64; 3],
        /// Signed sweep, rad.
        sweep_rad: f64,
        /// Arc plane.
        plane: Plane,
        /// Feed, mm/min.
        feed_mm_min: f64,
    },
}

/// A feature of the path and its parameters' meaning.
#[derive(Clone, Debug)]
pub enum Feature {
    /// A corner between two blocks.
    Corner {
        /// The corner point, mm.
        at: [f64; 3],
        /// Unit outward bisector (away from the inside of the turn).
        n: [f64; 3],
        /// Unit mean direction of travel.
        m: [f64; 3],
        /// Source line of the block ending at the corner.
        line: usize,
    },
    /// An arc (program block index) whose radius may change.
    Arc {
        /// Block index.
        block: usize,
        /// Source line.
        line: usize,
    },
}

impl Feature {
    /// Number of parameters.
    pub fn size(&self) -> usize {
        match self {
            Feature::Corner { .. } => 4,
            Feature::Arc { .. } => 1,
        }
    }
}

/// The features of a program with their parameters' bounds, start and difference steps.
#[derive(Clone, Debug, Default)]
pub struct Shape {
    /// The features, in path order.
    pub features: Vec<Feature>,
    /// Index of each feature's first parameter.
    pub offset: Vec<usize>,
    /// Lower bounds.
    pub lo: Vec<f64>,
    /// Upper bounds.
    pub hi: Vec<f64>,
    /// Start.
    pub x0: Vec<f64>,
    /// Finite-difference step of each parameter.
    pub step: Vec<f64>,
    /// Path-length window (mm) each feature can change the error in.
    pub window: Vec<(f64, f64)>,
    /// Corner feature ending each block / starting it; arc feature of each block.
    end_corner: Vec<Option<usize>>,
    start_corner: Vec<Option<usize>>,
    arc: Vec<Option<usize>>,
    /// Transition length of each block's arc ends (mm), where it has an arc feature.
    transition: Vec<f64>,
}

/// What the setup knows of the original run near each block, to start and bound the
/// parameters.
pub struct Near {
    /// Largest distance of the original's tool tip to the path over each block, mm.
    pub max_dist: Vec<f64>,
    /// Mean signed distance towards each arc's centre (the servo's radius loss), mm.
    pub inside: Vec<f64>,
}

/// A predicate on a program's block index.
pub type BlockTest<'a> = &'a dyn Fn(usize) -> bool;

/// Feed of a block in mm/min (`None` for rapids and inverse time).
fn feed_of(b: &Block) -> Option<f64> {
    match b.feed {
        Feed::PerMinute(f) => Some(f),
        _ => None,
    }
}

impl Shape {
    /// The features of `program`'s blocks for which `movable(block)` holds (cutting,
    /// G94, the only block of its line), on `machine`; a corner at the end of a block for
    /// which `placed_xy(block)` fails (the written program cannot state X or Y there) is
    /// only slowed, and so is a corner across blocks for which `through(block)` holds (a
    /// backlash take-up between its two blocks, written as it is). `path` gives the windows, `near` the original's errors; `band_mm` the
    /// smallest reach.
    pub fn new(
        program: &Program,
        path: &Path,
        machine: &Machine,
        (movable, placed_xy, through): (BlockTest<'_>, BlockTest<'_>, BlockTest<'_>),
        near: &Near,
        band_mm: f64,
    ) -> Shape {
        let nb = program.blocks.len();
        let kv = machine
            .axes
            .iter()
            .take(3)
            .map(|a| a.servo.kv)
            .fold(f64::INFINITY, f64::min);
        let accel = machine
            .axes
            .iter()
            .take(3)
            .map(|a| a.limits.max_accel)
            .fold(f64::INFINITY, f64::min);
        // The slowest model's time constant (kv −15 %) bounds how far a change reaches.
        let tau = 1.0 / (kv * (1.0 - super::models::KV_SPREAD));
        let seg_of: Vec<Option<usize>> = {
            let mut v = vec![None; nb];
            for (k, s) in path.segs.iter().enumerate() {
                v[s.block] = Some(k);
            }
            v
        };
        let mut sh = Shape {
            end_corner: vec![None; nb],
            start_corner: vec![None; nb],
            arc: vec![None; nb],
            transition: vec![0.0; nb],
            ..Shape::default()
        };
        let settle = |v: f64| super::SETTLE_TIME_CONSTANTS * tau * v;
        for i in 0..nb {
            let (Some(si), true) = (seg_of[i], movable(i)) else {
                continue;
            };
            let b = &program.blocks[i];
            let seg = &path.segs[si];
            let f_mm_s = feed_of(b).unwrap_or(0.0) / 60.0;
            // A corner with the next block, across take-ups.
            let mut j = i + 1;
            while j < nb && through(j) {
                j += 1;
            }
            if j < nb
                && movable(j)
                && let Some(sj) = seg_of[j]
            {
                let next = &path.segs[sj];
                let u1 = seg.geom.tangent(1.0);
                let u2 = next.geom.tangent(0.0);
                let turn = dot(u1, u2).clamp(-1.0, 1.0).acos();
                if turn >= CORNER_MIN_RAD {
                    let at = b.end.xyz;
                    let d = sub(u1, u2);
                    let n = scale(d, 1.0 / norm(d).max(1e-300));
                    let mm = add(u1, u2);
                    let m = if norm(mm) > 1e-9 {
                        scale(mm, 1.0 / norm(mm))
                    } else {
                        [0.0; 3]
                    };
                    let planar = level(&seg.geom).is_some()
                        && level(&seg.geom) == level(&next.geom)
                        && placed_xy(i)
                        && j == i + 1;
                    let reach = if planar {
                        REACH_FACTOR * near.max_dist[i].max(near.max_dist[j]).max(band_mm)
                    } else {
                        0.0
                    };
                    let lmax = MAX_LENGTH_SHARE * seg.len.min(next.len);
                    let v = f_mm_s.max(feed_of(&program.blocks[j]).unwrap_or(0.0) / 60.0);
                    let braking = v * v / (2.0 * accel);
                    let l0 = (TRANSITION_TIME_CONSTANTS * tau * v + braking).min(lmax);
                    let s_at = seg.s0 + seg.len;
                    let k = sh.features.len();
                    sh.add(
                        Feature::Corner {
                            at,
                            n,
                            m,
                            line: b.line,
                        },
                        &[-reach, -reach, 0.02 * lmax, MIN_FEED_FRACTION],
                        &[reach, reach, lmax, 1.0],
                        &[0.0, 0.0, l0, START_FEED_FRACTION],
                        &[
                            (0.05 * reach).max(1e-4),
                            (0.05 * reach).max(1e-4),
                            (0.05 * lmax).max(1e-4),
                            0.03,
                        ],
                        (s_at - lmax - braking, s_at + lmax + settle(v)),
                    );
                    sh.end_corner[i] = Some(k);
                    sh.start_corner[j] = Some(k);
                }
            }
        }
        // Arcs, after the corners: a feature's window is all that matters for its order.
        for (i, &si) in seg_of.iter().enumerate() {
            let (Some(si), true) = (si, movable(i)) else {
                continue;
            };
            let seg = &path.segs[si];
            let Geom::Arc {
                plane: Plane::Xy,
                radius,
                ..
            } = seg.geom
            else {
                continue;
            };
            let v = feed_of(&program.blocks[i]).unwrap_or(0.0) / 60.0;
            let trans = (TRANSITION_TIME_CONSTANTS * tau * v).min(MAX_LENGTH_SHARE * seg.len);
            if trans <= 0.0 || radius <= 0.0 {
                continue;
            }
            let reach = REACH_FACTOR * near.max_dist[i].max(band_mm);
            sh.transition[i] = trans;
            sh.arc[i] = Some(sh.features.len());
            sh.add(
                Feature::Arc {
                    block: i,
                    line: program.blocks[i].line,
                },
                &[-reach.min(0.5 * radius)],
                &[reach],
                &[near.inside[i]],
                &[(0.05 * reach).max(1e-4)],
                (seg.s0, seg.s0 + seg.len + settle(v)),
            );
        }
        sh
    }

    /// Appends feature `f` with its bounds, start (clamped into them), steps and window.
    fn add(&mut self, f: Feature, lo: &[f64], hi: &[f64], x0: &[f64], st: &[f64], w: (f64, f64)) {
        self.offset.push(self.lo.len());
        self.features.push(f);
        self.lo.extend_from_slice(lo);
        self.hi.extend_from_slice(hi);
        self.x0.extend(
            x0.iter()
                .zip(lo.iter().zip(hi))
                .map(|(x, (l, h))| x.clamp(*l, *h)),
        );
        self.step.extend_from_slice(st);
        self.window.push(w);
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.lo.len()
    }

    /// True when there is nothing to change.
    pub fn is_empty(&self) -> bool {
        self.lo.is_empty()
    }

    /// The corner point of corner feature `k` under parameters `x`, mm.
    fn corner_point(&self, k: usize, x: &[f64]) -> [f64; 3] {
        let Feature::Corner { at, n, m, .. } = &self.features[k] else {
            unreachable!("corner_point of a corner")
        };
        let o = self.offset[k];
        add(add(*at, scale(*n, x[o])), scale(*m, x[o + 1]))
    }

    /// Length and feed fraction of corner feature `k` under `x`.
    fn slow(&self, k: usize, x: &[f64]) -> (f64, f64) {
        let o = self.offset[k];
        (x[o + 2], x[o + 3])
    }

    /// The pieces of block `i` under `x`, starting where the block before ended (`start`,
    /// mm); `None` when the block is written as programmed.
    pub fn pieces(
        &self,
        program: &Program,
        i: usize,
        start: [f64; 3],
        x: &[f64],
    ) -> Option<Vec<Piece>> {
        // A corner at full feed whose point stays, an arc whose radius stays: no feature.
        let corner_on = |k: &usize| {
            let o = self.offset[*k];
            x[o + 3] < 1.0 || x[o] != 0.0 || x[o + 1] != 0.0
        };
        let cs = self.start_corner[i].filter(corner_on);
        let ce = self.end_corner[i].filter(corner_on);
        let ca = self.arc[i].filter(|k| x[self.offset[*k]] != 0.0);
        if cs.is_none() && ce.is_none() && ca.is_none() {
            return None;
        }
        let b = &program.blocks[i];
        let feed = feed_of(b)?;
        let end = match ce {
            Some(k) => self.corner_point(k, x),
            None => b.end.xyz,
        };
        let (ls, fs) = cs.map_or((0.0, 1.0), |k| self.slow(k, x));
        let (le, fe) = ce.map_or((0.0, 1.0), |k| self.slow(k, x));
        let geom = Geom::of(b)?;
        let mut out = Vec::with_capacity(3);
        match geom {
            Geom::Line { a, b: e } => {
                let len = norm(sub(e, a));
                let u = scale(sub(e, a), 1.0 / len.max(1e-300));
                if fs < 1.0 {
                    out.push(Piece::Line {
                        end: add(a, scale(u, ls)),
                        feed_mm_min: fs * feed,
                    });
                }
                if fe < 1.0 {
                    out.push(Piece::Line {
                        end: sub(e, scale(u, le)),
                        feed_mm_min: feed,
                    });
                }
                out.push(Piece::Line {
                    end,
                    feed_mm_min: fe * feed,
                });
            }
            Geom::Arc {
                plane,
                a,
                b: e,
                centre,
                radius,
                sweep,
            } => {
                let dr = ca.map_or(0.0, |k| x[self.offset[k]]);
                let len = geom.len();
                let trans = self.transition[i];
                let stretch = |l: f64, f: f64| {
                    if f < 1.0 {
                        l
                    } else if ca.is_some() {
                        trans
                    } else {
                        0.0
                    }
                };
                let t_in = stretch(ls, fs) / len;
                let t_out = stretch(le, fe) / len;
                let (p0, p1, nrm) = plane.axes();
                let on = |t: f64| {
                    let mut q = geom.at(t);
                    let r = radius + dr;
                    let ang = (q[p1] - centre[p1]).atan2(q[p0] - centre[p0]);
                    q[p0] = centre[p0] + r * ang.cos();
                    q[p1] = centre[p1] + r * ang.sin();
                    q[nrm] = a[nrm] + (e[nrm] - a[nrm]) * t;
                    q
                };
                let arc = |from: [f64; 3], to: [f64; 3], sw: f64, f: f64, exact: bool| {
                    if exact {
                        Some(Piece::Arc {
                            end: to,
                            centre,
                            sweep_rad: sw,
                            plane,
                            feed_mm_min: f,
                        })
                    } else {
                        sub_arc(plane, from, to, centre, sw).map(|s| Piece::Arc {
                            end: s.end_mm,
                            centre: s.centre_mm,
                            sweep_rad: s.sweep_rad,
                            plane,
                            feed_mm_min: f,
                        })
                    }
                };
                let pa = if t_in > 0.0 { on(t_in) } else { start };
                let pb = if t_out > 0.0 { on(1.0 - t_out) } else { end };
                if t_in > 0.0 {
                    out.extend(arc(start, pa, sweep * t_in, fs * feed, false));
                }
                // The middle piece runs about the original centre when both its ends lie on one
                // circle about it; otherwise (a moved corner point at an unslowed end) it is
                // the circle through its ends nearest to that centre.
                let rad = |q: [f64; 3]| (q[p0] - centre[p0]).hypot(q[p1] - centre[p1]);
                let exact = (rad(pa) - rad(pb)).abs() < 1e-9;
                out.extend(arc(pa, pb, sweep * (1.0 - t_in - t_out), feed, exact));
                if t_out > 0.0 {
                    out.extend(arc(pb, end, sweep * t_out, fe * feed, false));
                }
            }
        }
        Some(out)
    }

    /// The program `x` writes: `program` with each changed block replaced by its pieces
    /// (same source line); the pieces of every changed block, by block index.
    pub fn program(&self, program: &Program, x: &[f64]) -> (Program, Vec<(usize, Vec<Piece>)>) {
        let mut blocks = Vec::with_capacity(program.blocks.len() + 2 * self.features.len());
        let mut changed = Vec::new();
        let mut at: Option<[f64; 3]> = None;
        for (i, b) in program.blocks.iter().enumerate() {
            let start = at.unwrap_or(b.start.xyz);
            match self.pieces(program, i, start, x) {
                Some(pieces) => {
                    let mut from = start;
                    for p in &pieces {
                        let (end, motion, f) = match *p {
                            Piece::Line { end, feed_mm_min } => (end, Motion::Linear, feed_mm_min),
                            Piece::Arc {
                                end,
                                centre,
                                sweep_rad,
                                plane,
                                feed_mm_min,
                            } => (
                                end,
                                Motion::Arc {
                                    plane,
                                    center: centre,
                                    sweep_rad,
                                },
                                feed_mm_min,
                            ),
                        };
                        blocks.push(Block {
                            line: b.line,
                            motion,
                            start: Pose {
                                xyz: from,
                                ..b.start
                            },
                            end: Pose { xyz: end, ..b.end },
                            feed: Feed::PerMinute(f),
                            rtcp: b.rtcp,
                        });
                        from = end;
                    }
                    at = Some(from);
                    changed.push((i, pieces));
                }
                None => {
                    let mut c = b.clone();
                    c.start.xyz = start;
                    if !matches!(b.motion, Motion::Dwell { .. }) {
                        at = Some(b.end.xyz);
                    }
                    blocks.push(c);
                }
            }
        }
        (
            Program {
                blocks,
                first_a_line: program.first_a_line,
                first_c_line: program.first_c_line,
            },
            changed,
        )
    }

    /// Resets feature `k` of `x` to no change (a corner: f = 1, δ = 0; an arc: ΔR = 0);
    /// whether it changed anything.
    pub fn neutralize(&self, x: &mut [f64], k: usize) -> bool {
        let o = self.offset[k];
        match self.features[k] {
            Feature::Corner { .. } => {
                let was = x[o] != 0.0 || x[o + 1] != 0.0 || x[o + 3] != 1.0;
                x[o] = 0.0;
                x[o + 1] = 0.0;
                x[o + 3] = 1.0;
                was
            }
            Feature::Arc { .. } => {
                let was = x[o] != 0.0;
                x[o] = 0.0;
                was
            }
        }
    }

    /// Parameters that change nothing worth a block: a corner whose feed fraction is within
    /// `feed_tol` of 1 and whose point moved less than `move_tol_mm` is reset to no corner
    /// (f = 1, δ = 0), an arc whose radius changes by less than `move_tol_mm` to ΔR = 0.
    /// Returns the features so dropped.
    pub fn prune(&self, x: &mut [f64], feed_tol: f64, move_tol_mm: f64) -> Vec<usize> {
        let mut dropped = Vec::new();
        for (k, f) in self.features.iter().enumerate() {
            let o = self.offset[k];
            match f {
                Feature::Corner { .. } => {
                    if x[o + 3] >= 1.0 - feed_tol && x[o].hypot(x[o + 1]) < move_tol_mm {
                        x[o] = 0.0;
                        x[o + 1] = 0.0;
                        x[o + 3] = 1.0;
                        dropped.push(k);
                    }
                }
                Feature::Arc { .. } => {
                    if x[o].abs() < move_tol_mm {
                        x[o] = 0.0;
                        dropped.push(k);
                    }
                }
            }
        }
        dropped
    }
}

/// The Z of a block that stays in one XY level (a line or G17 arc at one Z), mm.
fn level(g: &Geom) -> Option<f64> {
    let (a, b) = match *g {
        Geom::Line { a, b } => (a, b),
        Geom::Arc {
            plane: Plane::Xy,
            a,
            b,
            ..
        } => (a, b),
        Geom::Arc { .. } => return None,
    };
    ((a[2] - b[2]).abs() < 1e-9).then_some(a[2])
}
