//! The program's path-control modes ([`PathControl`]: G61, G61.1, G9, G64 P, look-ahead off)
//! applied by the interpolator:
//!
//! - [`BlockEnd::Stop`]: the junction after the block gets speed 0, so the S-curve of the
//!   block ramps down to rest at its end point and the next one starts from rest (exact
//!   stop; Fanuc G61/G09, LinuxCNC G61.1);
//! - [`BlockEnd::Blend`]: the corner after the block is replaced by LinuxCNC's blend arc
//!   within the tolerance ([`super::blend`]), which the look-ahead then runs through at the
//!   arc's curvature limit instead of slowing to the corner rule's speed;
//! - [`BlockEnd::Continuous`]: nothing changes (the service's look-ahead).

use super::Seg;
use super::blend::{CornerLines, blend_arc};
use crate::motion::gcode::{Block, Feed, Motion, Pose};
use crate::motion::machine::Machine;
use crate::motion::path_control::{BlockEnd, PathControl};

/// The two straight moves `a` → `b` as a corner to blend, or None when they are not two
/// straight moves of the program frame (RTCP off, A and C still) meeting end to start with
/// feeds of one kind (both rapid or both per minute). `len_a` is `a`'s programmed length
/// (a blend at its start may have shortened it).
fn corner_lines(a: &Block, b: &Block, len_a: f64) -> Option<CornerLines> {
    let still = |k: &Block| k.start.a == k.end.a && k.start.c == k.end.c;
    let straight = |k: &Block| matches!(k.motion, Motion::Linear) && !k.rtcp && still(k);
    let same_feed_kind = matches!(
        (a.feed, b.feed),
        (Feed::Rapid, Feed::Rapid) | (Feed::PerMinute(_), Feed::PerMinute(_))
    );
    let joined = (0..3).all(|i| (a.end.xyz[i] - b.start.xyz[i]).abs() <= 1e-9)
        && a.end.a == b.start.a
        && a.end.c == b.start.c;
    if !(straight(a) && straight(b) && same_feed_kind && joined) {
        return None;
    }
    let (left, len_b) = (a.xyz_length(), b.xyz_length());
    if left <= 0.0 || len_b <= 0.0 {
        return None;
    }
    Some(CornerLines {
        corner: a.end.xyz,
        u1: std::array::from_fn(|i| (a.end.xyz[i] - a.start.xyz[i]) / left),
        u2: std::array::from_fn(|i| (b.end.xyz[i] - b.start.xyz[i]) / len_b),
        len1_left: left,
        len1: len_a,
        len2: len_b,
        feed1: a.feed,
        feed2: b.feed,
    })
}

/// Replaces every corner whose first block ends in [`BlockEnd::Blend`] by LinuxCNC's blend
/// arc ([`blend_arc`]): the first line now ends where the arc starts, the arc (carrying the
/// first block's source line) follows, the second line starts where it ends. Corners that
/// cannot be blended are left as programmed (the look-ahead's corner rule applies).
pub(super) fn blend_corners(
    blocks: Vec<Block>,
    control: &PathControl,
    machine: &Machine,
) -> Vec<Block> {
    if control.is_continuous() {
        return blocks;
    }
    let mut out: Vec<Block> = Vec::with_capacity(blocks.len());
    let mut len_last = 0.0;
    for mut b in blocks {
        let len_b = b.xyz_length();
        let arc = out.last().and_then(|a| {
            let BlockEnd::Blend { tolerance_mm } = control.end_of(a.line) else {
                return None;
            };
            blend_arc(&corner_lines(a, &b, len_last)?, tolerance_mm, machine)
        });
        if let (Some(arc), Some(a)) = (arc, out.last_mut()) {
            a.end.xyz = arc.start;
            let at = |xyz| Pose {
                xyz,
                a: b.start.a,
                c: b.start.c,
            };
            let blend = Block {
                line: a.line,
                motion: arc.motion,
                start: at(arc.start),
                end: at(arc.end),
                feed: arc.feed,
                rtcp: false,
            };
            out.push(blend);
            b.start.xyz = arc.end;
        }
        out.push(b);
        len_last = len_b;
    }
    out
}

/// Sets the speed of every junction after a block that ends in [`BlockEnd::Stop`] to 0
/// (`v[k]` enters item `k`; dwells carry no segment and already stop the tool).
pub(super) fn stop_junctions(
    items: &[(&Block, Option<Seg>)],
    control: &PathControl,
    v: &mut [f64],
) {
    for k in 1..items.len() {
        let (b, seg) = &items[k - 1];
        if seg.is_some() && control.end_of(b.line) == BlockEnd::Stop {
            v[k] = 0.0;
        }
    }
}

#[cfg(test)]
mod tests;
