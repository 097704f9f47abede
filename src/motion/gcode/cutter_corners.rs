//! The corners of cutter radius compensation (`super::cutter`): where a move after the
//! entry starts and ends, from the corner it makes with the move held before it, as
//! LinuxCNC's interpreter decides it (rs274ngc's second straight and arc compensation).
//!
//! Angles: `theta` is the direction of the tool from the last programmed point (square to the
//! last move), `alpha` the direction in which the new move leaves that point; `beta`, the
//! turn between them, says what the corner is: within [`CORNER_RAD`] of straight, nothing
//! to add; an outside (convex) corner, an arc of the tool radius round the programmed corner;
//! an inside (concave) corner, beyond π by more than [`CORNER_RAD`], both moves trimmed to
//! where their offset paths cross (line-line, line-arc, arc-line and arc-arc each by its own
//! construction).

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use super::cutter::{Cutter, Held, Side, dist, inside, polar, sweep, too_small, with_xy, xy};
use crate::motion::error::Error;
use crate::motion::program::{Block, Feed, Pose};

/// Turn, rad, within which a corner counts as straight, and beyond π by which it counts as
/// inside: LinuxCNC's TOLERANCE_CONCAVE_CORNER (0.05 rad, about 2.9°).
const CORNER_RAD: f64 = 0.05;

/// The error of an inside corner that no tool position reaches without cutting the part.
fn no_fit(line: usize, what: &str) -> Error {
    Error::gcode(
        line,
        format!(
            "cutter compensation: the tool does not fit in the inside corner {what} without \
             gouging (LinuxCNC refuses it too): use a smaller tool or change the contour"
        ),
    )
}

impl Cutter {
    /// The held move's arc (centre, turn, radius to its end), when the first held move is one.
    fn held_arc(&self) -> Option<([f64; 2], i32, f64)> {
        match self.held.first() {
            Some(p) => match p.held {
                Held::Arc { centre, turn, .. } => Some((centre, turn, dist(centre, xy(&p.end)))),
                _ => None,
            },
            None => None,
        }
    }

    /// A line (or traverse, `feed` Rapid) after the entry, to the programmed `to`.
    pub(super) fn straight_corner(
        &mut self,
        line: usize,
        feed: Feed,
        to: Pose,
    ) -> Result<Vec<Block>, Error> {
        let (c, op, p, r) = (xy(&self.tool), self.programmed, xy(&to), self.radius_mm);
        let mut out = Vec::new();
        if p == op {
            // No XY motion: held with the move before, at the tool's XY.
            let end = with_xy(to, c);
            self.hold(line, Held::Straight { dir: [0.0, 0.0] }, end, feed);
            self.tool = end;
            return Ok(out);
        }
        let side = self.side;
        let mut theta = (c[1] - op[1]).atan2(c[0] - op[0]);
        let mut alpha = (p[1] - op[1]).atan2(p[0] - op[0]);
        let (beta, gamma) = match side {
            Side::Left => {
                if theta < alpha {
                    theta += TAU;
                }
                (theta - alpha - FRAC_PI_2, FRAC_PI_2)
            }
            Side::Right => {
                if alpha < theta {
                    alpha += TAU;
                }
                (alpha - theta - FRAC_PI_2, -FRAC_PI_2)
            }
        };
        let end = polar(p, r, alpha + gamma);
        let mid = polar(op, r, alpha + gamma);
        let held_arc = self.held_arc();
        // An "h": over an arc and on along a line beside it; stay outside (LinuxCNC forces it).
        let h_shape = beta > PI - CORNER_RAD
            && held_arc.is_some_and(|(_, turn, _)| inside(side.flipped(), turn));
        let concave = !(-CORNER_RAD..=PI + CORNER_RAD).contains(&beta) || h_shape;
        if concave {
            let corner = match held_arc {
                None => {
                    // Line-line: back along the held line by r / tan(half the inside angle).
                    let half = (beta + PI) / 2.0;
                    if half == 0.0 {
                        return Err(no_fit(line, "of zero degrees"));
                    }
                    polar(c, r / half.tan(), theta + gamma)
                }
                Some((centre, turn, radius)) => {
                    arc_line_corner(side, r, op, p, centre, turn, radius)
                        .ok_or_else(|| no_fit(line, "between the arc and this line"))?
                }
            };
            out.extend(self.end_held_at(line, corner)?);
        } else if beta > CORNER_RAD {
            // Outside corner: round it on an arc of the tool radius (a G0 goes straight).
            out.extend(self.end_held_at(line, c)?);
            let corner_end = Pose {
                xyz: [mid[0], mid[1], self.tool.xyz[2]],
                ..to
            };
            let held = if feed == Feed::Rapid {
                Held::Straight { dir: [0.0, 0.0] }
            } else {
                let turn = if side == Side::Left { -1 } else { 1 };
                Held::Arc {
                    centre: op,
                    turn,
                    sweep_rad: 0.0,
                }
            };
            self.hold(line, held, corner_end, feed);
            out.extend(self.release());
            self.endpoint = Some(mid);
        } else {
            // Straight on, or tangent from an arc.
            out.extend(self.release());
            self.endpoint = Some(c);
        }
        let dir = [p[0] - op[0], p[1] - op[1]];
        let end_pose = with_xy(to, end);
        self.hold(line, Held::Straight { dir }, end_pose, feed);
        self.tool = end_pose;
        self.programmed = p;
        Ok(out)
    }

    /// An arc after the entry, to the programmed `to` round the programmed `centre` turning
    /// `turn` (+1 G3, −1 G2).
    pub(super) fn arc_corner(
        &mut self,
        line: usize,
        feed: Feed,
        to: Pose,
        centre: [f64; 2],
        turn: i32,
    ) -> Result<Vec<Block>, Error> {
        let (c, op, e, r) = (xy(&self.tool), self.programmed, xy(&to), self.radius_mm);
        let side = self.side;
        let arc_radius = dist(centre, e);
        let mut theta = (c[1] - op[1]).atan2(c[0] - op[0]);
        theta += if side == Side::Left {
            -FRAC_PI_2
        } else {
            FRAC_PI_2
        };
        let mut delta = (centre[1] - op[1]).atan2(centre[0] - op[0]);
        let alpha = if turn > 0 {
            delta - FRAC_PI_2
        } else {
            delta + FRAC_PI_2
        };
        let mut beta = if side == Side::Left {
            theta - alpha
        } else {
            alpha - theta
        };
        if beta > 1.5 * PI {
            beta -= TAU;
        } else if beta < -FRAC_PI_2 {
            beta += TAU;
        }
        let tool_inside = inside(side, turn);
        let gamma = if tool_inside {
            if arc_radius <= r {
                return Err(too_small(line, arc_radius, r));
            }
            (centre[1] - e[1]).atan2(centre[0] - e[0])
        } else {
            delta += PI;
            (e[1] - centre[1]).atan2(e[0] - centre[0])
        };
        let new_end = polar(e, r, gamma);
        let mut out = Vec::new();
        let concave = !(-CORNER_RAD..=PI + CORNER_RAD).contains(&beta)
            || ((beta - PI).abs() < CORNER_RAD && !tool_inside);
        if concave {
            let corner = match self.held_arc() {
                None => line_arc_corner(side, r, theta, beta, centre, turn, arc_radius)
                    .ok_or_else(|| no_fit(line, "between the line and this arc"))?,
                Some((prev_centre, prev_turn, prev_radius)) => {
                    if prev_radius == 0.0 || dist(prev_centre, centre) == 0.0 {
                        return Err(no_fit(line, "between two arcs of one centre"));
                    }
                    let arcs = (prev_centre, prev_turn, prev_radius);
                    arc_arc_corner(side, r, arcs, centre, turn, arc_radius)
                        .ok_or_else(|| no_fit(line, "between the two arcs"))?
                }
            };
            out.extend(self.end_held_at(line, corner)?);
        } else if beta > CORNER_RAD {
            // Outside corner: an arc of the tool radius round the programmed corner first.
            let mid = polar(op, r, delta);
            out.extend(self.release());
            let corner_end = Pose {
                xyz: [mid[0], mid[1], self.tool.xyz[2]],
                ..to
            };
            let round = if side == Side::Left { -1 } else { 1 };
            let held = Held::Arc {
                centre: op,
                turn: round,
                sweep_rad: 0.0,
            };
            self.hold(line, held, corner_end, feed);
            out.extend(self.release());
            self.endpoint = Some(mid);
        } else {
            out.extend(self.release());
            self.endpoint = Some(c);
        }
        let held = Held::Arc {
            centre,
            turn,
            sweep_rad: sweep(op, centre, turn, e),
        };
        let end_pose = with_xy(to, new_end);
        self.hold(line, held, end_pose, feed);
        self.tool = end_pose;
        self.programmed = e;
        Ok(out)
    }
}

/// Inside corner from a held (compensated) arc round `centre` (radius `radius`, turning
/// `turn`) into the line from `op` to `p`: the point of the held arc one tool radius `r`
/// from the line, on the material side. None: the tool does not fit.
fn arc_line_corner(
    side: Side,
    r: f64,
    op: [f64; 2],
    p: [f64; 2],
    centre: [f64; 2],
    turn: i32,
    radius: f64,
) -> Option<[f64; 2]> {
    let base = (p[1] - op[1]).atan2(p[0] - op[0]);
    let theta = if turn > 0 {
        base + FRAC_PI_2
    } else {
        base - FRAC_PI_2
    };
    let phi = (centre[1] - op[1]).atan2(centre[0] - op[0]);
    let tool_inside = inside(side, turn);
    let programmed_radius = if tool_inside { radius + r } else { radius - r };
    // Distance of the arc's centre from the new line, along the line's normal.
    let d = programmed_radius * (theta - phi).cos();
    let (l, sign) = if tool_inside {
        ((d - r) / radius, -1.0)
    } else {
        ((d + r) / radius, 1.0)
    };
    if !(-1.0..=1.0).contains(&l) {
        return None;
    }
    let turn_sign = if turn > 0 { sign } else { -sign };
    let angle = turn_sign * l.acos() + theta + PI;
    Some(polar(centre, radius, angle))
}

/// Inside corner from a held line into an arc round `centre` (programmed radius
/// `arc_radius`, turning `turn`): where the line's offset meets the arc's offset circle.
/// `theta` is the held line's direction, `beta` the corner's turn. None: no such point.
fn line_arc_corner(
    side: Side,
    r: f64,
    theta: f64,
    beta: f64,
    centre: [f64; 2],
    turn: i32,
    arc_radius: f64,
) -> Option<[f64; 2]> {
    let across = arc_radius * (beta - FRAC_PI_2).sin();
    let (radius, toward, tool_inside) = if inside(side, turn) {
        (arc_radius - r, across + r, true)
    } else {
        (arc_radius + r, across - r, false)
    };
    let l = toward / radius;
    if !(-1.0..=1.0).contains(&l) {
        return None;
    }
    let angle = match (tool_inside, turn > 0) {
        (true, true) => theta + l.asin(),
        (true, false) => theta - l.asin(),
        (false, true) => theta + PI - l.asin(),
        (false, false) => theta + PI + l.asin(),
    };
    Some(polar(centre, radius, angle))
}

/// Inside corner between a held (compensated) arc `(centre, turn, radius)` and the next arc
/// round `centre` (programmed `arc_radius`, turning `turn`): where the two offset circles
/// cross, on the held arc. None: they do not cross.
fn arc_arc_corner(
    side: Side,
    r: f64,
    held: ([f64; 2], i32, f64),
    centre: [f64; 2],
    turn: i32,
    arc_radius: f64,
) -> Option<[f64; 2]> {
    let (prev_centre, prev_turn, old) = held;
    let new = if inside(side, turn) {
        arc_radius - r
    } else {
        arc_radius + r
    };
    let cc = dist(prev_centre, centre);
    let a = (old * old + cc * cc - new * new) / (2.0 * old * cc);
    if !(-1.0..=1.0).contains(&a) {
        return None;
    }
    let pullback = a.acos();
    let cc_dir = (centre[1] - prev_centre[1]).atan2(centre[0] - prev_centre[0]);
    let plus = inside(side, prev_turn) == (turn > 0);
    let dir = if plus {
        cc_dir + pullback
    } else {
        cc_dir - pullback
    };
    Some(polar(prev_centre, old, dir))
}
