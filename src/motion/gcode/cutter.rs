//! Cutter radius compensation (G41/G42) in the XY plane: the tool-centre path of a programmed
//! contour, computed as LinuxCNC's interpreter computes it (rs274ngc's straight and arc
//! compensation and its queue of held moves; LinuxCNC User Manual, "Cutter Compensation"), so
//! that the two readers agree move for move (`tests/gcode_oracle`).
//!
//! - Entry, the first move after G41/G42: a line ends one tool radius to the side of its
//!   programmed end, square to the move, and must be longer than the radius. An arc entry
//!   ends on its offset circle, its centre moved so that the arc starts at the tool.
//! - Every later move ends one radius off its programmed end, square to the path there. The
//!   corner with the move before decides where that move ends (`super::cutter_corners`):
//!   outside corners get an arc of the tool radius round the programmed corner (a G0 a
//!   straight traverse), inside corners trim both moves to where their offset paths cross,
//!   and a straight or tangent continuation changes nothing. So a move is held until the
//!   next one is read; moves without XY motion and dwells are held with it.
//! - Exit, G40: the held moves end where they are; the next move starts from the tool centre
//!   and goes to its programmed end (the reader checks that it is a line).
//!
//! Where the tool cannot follow (an inside corner or an arc too small for the tool), the
//! error names the line and why, as LinuxCNC refuses it. All lengths are mm in the machine
//! frame (the reader's), so a G20/G21 switch changes nothing here.

use std::f64::consts::{FRAC_PI_2, TAU};

use crate::motion::error::Error;
use crate::motion::program::{Block, Feed, Motion, Plane, Pose};

/// Growth of a held arc's sweep, rad, beyond which moving its end to an inside corner would
/// run the tool back along it (a gouge), in a G20 program: LinuxCNC's 0.001.
const SWEEP_GROWTH_INCH_RAD: f64 = 0.001;
/// The same in a G21 program: LinuxCNC scales the angle like a length, 0.001 × 25.4 (checked
/// on rs274: an arc whose sweep grows by 0.0022 rad passes in G21 and is refused in G20).
const SWEEP_GROWTH_MM_RAD: f64 = 0.0254;
/// Change of a held arc's radius, mm, beyond which moving its end is a fault of this module
/// (the new end must lie on the arc; LinuxCNC checks 0.01 program units).
const ARC_RADIUS_SLACK_MM: f64 = 0.01;
/// |cos| of the entry arc's construction angle below which no centre exists: the tool
/// radius is not less than the arc's (LinuxCNC's TOLERANCE_EQUAL).
const ENTRY_COS_MIN: f64 = 1e-4;

/// Which side of the programmed path the tool runs on, looking along the motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Side {
    /// G41.
    Left,
    /// G42.
    Right,
}

impl Side {
    /// +1 left, −1 right: the offset is `sign` × 90° from the direction of motion.
    pub(super) fn sign(self) -> f64 {
        match self {
            Side::Left => 1.0,
            Side::Right => -1.0,
        }
    }

    /// The other side (a negative diameter swaps sides, as in LinuxCNC).
    pub(crate) fn flipped(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }
}

/// True when the tool runs inside an arc turning `turn` (+1 G3, −1 G2) on `side`.
pub(super) fn inside(side: Side, turn: i32) -> bool {
    (side == Side::Left && turn > 0) || (side == Side::Right && turn < 0)
}

/// Signed sweep, rad, from `a` to `b` round `centre` turning `turn` (+1 counter-clockwise,
/// −1 clockwise): in (0, 2π] or [−2π, 0); equal points are a full turn (LinuxCNC's
/// `find_turn`).
pub(super) fn sweep(a: [f64; 2], centre: [f64; 2], turn: i32, b: [f64; 2]) -> f64 {
    let alpha = (a[1] - centre[1]).atan2(a[0] - centre[0]);
    let beta = (b[1] - centre[1]).atan2(b[0] - centre[0]);
    if turn > 0 {
        let beta = if beta <= alpha { beta + TAU } else { beta };
        beta - alpha
    } else {
        let alpha = if alpha <= beta { alpha + TAU } else { alpha };
        beta - alpha
    }
}

pub(super) fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

pub(super) fn xy(p: &Pose) -> [f64; 2] {
    [p.xyz[0], p.xyz[1]]
}

/// `to` with its XY replaced by `p`.
pub(super) fn with_xy(to: Pose, p: [f64; 2]) -> Pose {
    let mut out = to;
    out.xyz[0] = p[0];
    out.xyz[1] = p[1];
    out
}

/// `p` + `r` along angle `a`.
pub(super) fn polar(p: [f64; 2], r: f64, a: f64) -> [f64; 2] {
    [p[0] + r * a.cos(), p[1] + r * a.sin()]
}

/// How a held move may still change when the next corner moves its end.
#[derive(Clone, Copy, Debug)]
pub(super) enum Held {
    /// A line or traverse; `dir` is the direction it was enqueued with (moving its end
    /// against it would reverse it).
    Straight { dir: [f64; 2] },
    /// An arc round `centre` turning `turn`, first swept `sweep_rad` (0: not checked).
    Arc {
        centre: [f64; 2],
        turn: i32,
        sweep_rad: f64,
    },
    /// A dwell where the tool stands.
    Dwell { seconds: f64 },
}

/// A move handed to the compensation and not yet given out.
#[derive(Clone, Debug)]
pub(super) struct Pending {
    pub(super) line: usize,
    pub(super) held: Held,
    pub(super) end: Pose,
    pub(super) feed: Feed,
}

/// The compensation in force between G41/G42 and G40.
#[derive(Clone, Debug)]
pub(crate) struct Cutter {
    pub(super) side: Side,
    pub(super) radius_mm: f64,
    /// No move read yet since G41/G42.
    pub(super) first: bool,
    /// Programmed XY of the last move read.
    pub(super) programmed: [f64; 2],
    /// Tool centre after the held moves.
    pub(super) tool: Pose,
    pub(super) held: Vec<Pending>,
    /// Where the held moves start (LinuxCNC's queue end point), when known.
    pub(super) endpoint: Option<[f64; 2]>,
    /// Where the last move given out ends: the start of the next.
    out: Pose,
    /// G20 in force (the reader keeps it current): chooses the sweep growth allowed.
    pub(crate) inch: bool,
}

impl Cutter {
    /// Compensation on `side` with a tool of `radius_mm` (> 0), from the programmed point
    /// `programmed` with the tool standing at `tool` (the two differ right after a G40).
    pub(crate) fn new(side: Side, radius_mm: f64, programmed: Pose, tool: Pose) -> Self {
        Cutter {
            side,
            radius_mm,
            first: true,
            programmed: xy(&programmed),
            tool: programmed,
            held: Vec::new(),
            endpoint: None,
            out: tool,
            inch: false,
        }
    }

    /// The held moves as blocks, chained from the last one given out (LinuxCNC's
    /// `dequeue_canons`).
    pub(super) fn release(&mut self) -> Vec<Block> {
        self.endpoint = None;
        let mut out = Vec::with_capacity(self.held.len());
        for p in self.held.drain(..) {
            let start = self.out;
            let (motion, end) = match p.held {
                Held::Straight { .. } => (Motion::Linear, p.end),
                Held::Arc { centre, turn, .. } => (
                    Motion::Arc {
                        plane: Plane::Xy,
                        center: [centre[0], centre[1], start.xyz[2]],
                        sweep_rad: sweep(xy(&start), centre, turn, xy(&p.end)),
                    },
                    p.end,
                ),
                Held::Dwell { seconds } => (Motion::Dwell { seconds }, start),
            };
            self.out = end;
            out.push(Block {
                line: p.line,
                motion,
                start,
                end,
                feed: p.feed,
                rtcp: false,
            });
        }
        out
    }

    /// Moves the XY end of every held move to `to` and gives them out (LinuxCNC's
    /// `move_endpoint_and_flush`); errors (on `line`) where that would run a held move
    /// backwards, i.e. the tool does not fit in the corner.
    pub(super) fn end_held_at(&mut self, line: usize, to: [f64; 2]) -> Result<Vec<Block>, Error> {
        let growth = if self.inch {
            SWEEP_GROWTH_INCH_RAD
        } else {
            SWEEP_GROWTH_MM_RAD
        };
        for p in &mut self.held {
            match p.held {
                Held::Arc {
                    centre,
                    turn,
                    sweep_rad,
                } => {
                    let (r1, r2) = (dist(xy(&p.end), centre), dist(to, centre));
                    if (r1 - r2).abs() > ARC_RADIUS_SLACK_MM {
                        return Err(Error::gcode(
                            line,
                            format!(
                                "cutter compensation moved the end of the arc of line {} off \
                                 its circle (radius {r1:.4} -> {r2:.4} mm): please report this \
                                 program",
                                p.line
                            ),
                        ));
                    }
                    if let Some(e) = self.endpoint
                        && sweep_rad != 0.0
                        && sweep(e, centre, turn, to).abs() > sweep_rad.abs() + growth
                    {
                        return Err(gouge(line, p.line, "arc"));
                    }
                }
                Held::Straight { dir } => {
                    if let Some(e) = self.endpoint {
                        let moved = [to[0] - e[0], to[1] - e[1]];
                        if dir[0] * moved[0] + dir[1] * moved[1] < 0.0 {
                            return Err(gouge(line, p.line, "straight move"));
                        }
                    }
                }
                Held::Dwell { .. } => {}
            }
            p.end.xyz[0] = to[0];
            p.end.xyz[1] = to[1];
        }
        let out = self.release();
        self.endpoint = Some(to);
        Ok(out)
    }

    /// Holds a move (the corner logic gives out what came before).
    pub(super) fn hold(&mut self, line: usize, held: Held, end: Pose, feed: Feed) {
        self.held.push(Pending {
            line,
            held,
            end,
            feed,
        });
    }

    /// A dwell: held behind the held moves, or given out at once when none is held.
    pub(crate) fn dwell(&mut self, line: usize, seconds: f64) -> Vec<Block> {
        self.hold(line, Held::Dwell { seconds }, self.tool, Feed::Rapid);
        if self.held.len() == 1 {
            return self.release();
        }
        Vec::new()
    }

    /// G40 (or the program's end) on `line`: the held moves end where they are; answers them
    /// and the tool centre, where the next move starts.
    pub(crate) fn finish(mut self, line: usize) -> Result<(Vec<Block>, Pose), Error> {
        let at = xy(&self.tool);
        let out = self.end_held_at(line, at)?;
        Ok((out, self.out))
    }

    /// A G0 (`feed` Rapid) or G1 to the programmed `to` on `line`; answers the moves given out.
    pub(crate) fn straight(
        &mut self,
        line: usize,
        feed: Feed,
        to: Pose,
    ) -> Result<Vec<Block>, Error> {
        if !self.first {
            return self.straight_corner(line, feed, to);
        }
        let (c, p, r) = (xy(&self.tool), xy(&to), self.radius_mm);
        let d = dist(c, p);
        if d <= r {
            return Err(Error::gcode(
                line,
                format!(
                    "cutter compensation: the entry move is not greater than the tool radius \
                     ({d:.4} mm in XY, radius {r} mm; LinuxCNC refuses it too): the first move \
                     after G41/G42 must move in X/Y by more than the radius"
                ),
            ));
        }
        let a = (p[1] - c[1]).atan2(p[0] - c[0]) + self.side.sign() * FRAC_PI_2;
        let end = polar(p, r, a);
        self.endpoint = Some(c);
        let end_pose = with_xy(to, end);
        let dir = [a.cos(), a.sin()];
        self.hold(line, Held::Straight { dir }, end_pose, feed);
        self.first = false;
        self.tool = end_pose;
        self.programmed = p;
        Ok(Vec::new())
    }

    /// A G2 (`turn` −1) or G3 (+1) to the programmed `to` round the programmed `centre` (XY).
    pub(crate) fn arc(
        &mut self,
        line: usize,
        feed: Feed,
        to: Pose,
        centre: [f64; 2],
        turn: i32,
    ) -> Result<Vec<Block>, Error> {
        if !self.first {
            return self.arc_corner(line, feed, to, centre, turn);
        }
        let (c, e, r) = (xy(&self.tool), xy(&to), self.radius_mm);
        if dist(c, e) <= r {
            return Err(Error::gcode(
                line,
                format!(
                    "cutter compensation: the entry arc's chord is not greater than the tool \
                     radius ({:.4} mm, radius {r} mm; LinuxCNC refuses it too): start G41/G42 \
                     farther from the contour",
                    dist(c, e)
                ),
            ));
        }
        let tool_inside = inside(self.side, turn);
        if dist(centre, c) <= r && tool_inside {
            return Err(too_small(line, dist(centre, c), r));
        }
        let gamma = if tool_inside {
            (centre[1] - e[1]).atan2(centre[0] - e[0])
        } else {
            (e[1] - centre[1]).atan2(e[0] - centre[0])
        };
        let end = polar(e, r, gamma);
        // The new centre B lies on the line from the new end A towards the old centre, at
        // equal distance from A and from the tool: half the chord over cos of the angle at A.
        let half = dist(c, end) / 2.0;
        let ab = (centre[1] - end[1]).atan2(centre[0] - end[0]);
        let angle_a = (c[1] - end[1]).atan2(c[0] - end[0]) - ab;
        if angle_a.cos().abs() < ENTRY_COS_MIN {
            return Err(too_small(line, dist(centre, e), r));
        }
        let new_centre = polar(end, half / angle_a.cos(), ab);
        let sweep_rad = sweep(c, new_centre, turn, end);
        let end_pose = with_xy(to, end);
        let held = Held::Arc {
            centre: new_centre,
            turn,
            sweep_rad,
        };
        self.hold(line, held, end_pose, feed);
        self.first = false;
        self.tool = end_pose;
        self.programmed = e;
        Ok(Vec::new())
    }
}

/// The error of a held move (from `held_line`) that an inside corner would run backwards.
fn gouge(line: usize, held_line: usize, what: &str) -> Error {
    Error::gcode(
        line,
        format!(
            "cutter compensation: the tool does not fit in the inside corner with the {what} of \
             line {held_line}: it would have to run that move backwards (LinuxCNC refuses it \
             too); use a smaller tool or a longer move"
        ),
    )
}

/// The error of an arc whose radius `arc_mm` is not greater than the tool's `tool_mm`, with
/// the tool inside it.
pub(super) fn too_small(line: usize, arc_mm: f64, tool_mm: f64) -> Error {
    Error::gcode(
        line,
        format!(
            "cutter compensation: the tool (radius {tool_mm} mm) does not fit inside this arc \
             (radius {arc_mm:.4} mm; LinuxCNC refuses it too): use a smaller tool"
        ),
    )
}

#[cfg(test)]
mod tests;
