//! Canned drilling cycles G73/G81/G82/G83/G85 expanded into the rapid and feed moves they
//! make (Fanuc semantics; Smid 2008 ch. 25, fixed cycles): rapid to the hole's XY, rapid to
//! the R plane, feed to Z, dwell P (G82), retract (feed for G85, rapid otherwise), then rapid
//! to the initial Z (G98) or stay at R (G99).
//!
//! Pecks (G73/G83 with Q) retract along the hole's own axis, so the path is the same line; the
//! time spent pecking depends on controller parameters (retract amount, clearance) the service
//! is not given, so the reader feeds straight to Z and says so in a warning.

use crate::motion::program::{Block, Feed, Motion, Pose};

/// A canned cycle in force (modal until G80 or a G0..G3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Cycle {
    /// G code (73, 81, 82, 83, 85).
    pub code: u32,
    /// Z of the initial level (where the cycle began), mm, machine frame.
    pub initial_z_mm: f64,
    /// Z of the R plane, mm, machine frame.
    pub r_z_mm: f64,
    /// Z of the hole bottom, mm, machine frame.
    pub bottom_z_mm: f64,
    /// G82 dwell at the bottom, s.
    pub dwell_s: f64,
}

impl Cycle {
    /// Blocks of one hole at `xy` (mm, machine frame) from `from`, on source `line`, at
    /// `feed`; `to_initial` is G98 (return to the initial level) versus G99 (to R).
    pub(crate) fn hole(
        &self,
        line: usize,
        from: Pose,
        xy: [f64; 2],
        feed: Feed,
        to_initial: bool,
        rtcp: bool,
    ) -> Vec<Block> {
        let mut path = Path {
            out: Vec::with_capacity(6),
            at: from,
            line,
            rtcp,
        };
        let mut p = from;
        p.xyz[0] = xy[0];
        p.xyz[1] = xy[1];
        path.go(p, Motion::Linear, Feed::Rapid);
        // Rapid down (or up) to R, feed to the bottom.
        p.xyz[2] = self.r_z_mm;
        path.go(p, Motion::Linear, Feed::Rapid);
        p.xyz[2] = self.bottom_z_mm;
        path.go(p, Motion::Linear, feed);
        if self.code == 82 && self.dwell_s > 0.0 {
            let seconds = self.dwell_s;
            path.go(p, Motion::Dwell { seconds }, Feed::Rapid);
        }
        p.xyz[2] = self.r_z_mm;
        let back = if self.code == 85 { feed } else { Feed::Rapid };
        path.go(p, Motion::Linear, back);
        if to_initial && self.initial_z_mm > self.r_z_mm {
            p.xyz[2] = self.initial_z_mm;
            path.go(p, Motion::Linear, Feed::Rapid);
        }
        path.out
    }
}

struct Path {
    out: Vec<Block>,
    at: Pose,
    line: usize,
    rtcp: bool,
}

impl Path {
    /// Appends a move to `to` (skipped when it would not move; dwells always kept).
    fn go(&mut self, to: Pose, motion: Motion, feed: Feed) {
        if to == self.at && motion == Motion::Linear {
            return;
        }
        self.out.push(Block {
            line: self.line,
            motion,
            start: self.at,
            end: to,
            feed,
            rtcp: self.rtcp,
        });
        self.at = to;
    }
}
