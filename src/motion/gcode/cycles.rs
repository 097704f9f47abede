//! Canned cycles expanded into the rapid and feed moves they make (Fanuc semantics; Smid
//! 2008 ch. 25, fixed cycles): rapid to the hole's XY (first up to the R plane when below
//! it, as LinuxCNC does), rapid to the R plane, feed to Z (in pecks for G73/G83), dwell P,
//! retract, then rapid to the initial Z (G98) or stay at R (G99).
//!
//! | code | in | at the bottom | out to R |
//! |---|---|---|---|
//! | G81 | feed | | rapid |
//! | G82 | feed | dwell | rapid |
//! | G73 | feed in pecks of Q, rapid back 0.254 mm between pecks | | rapid |
//! | G83 | feed in pecks of Q, rapid out to R and back down to 0.254 mm above the last depth | | rapid |
//! | G84, G74 | feed (tapping: F = S × pitch) | dwell, spindle reverses | feed |
//! | G85 | feed | | feed |
//! | G86 | feed | spindle stops | rapid |
//! | G87 | (back boring) rapid down to R below the part, feed up to Z | | rapid to the initial Z |
//! | G88 | feed | dwell, spindle stops, manual retract | rapid (on cycle start) |
//! | G89 | feed | dwell | feed |
//!
//! The peck retract (0.254 mm = 0.010 in) is LinuxCNC's fixed value; on a Fanuc control it is
//! a parameter (5114 for G73, 5115 for G83) the service is not given, so the reader says so
//! in a warning. LinuxCNC differs from Fanuc on two retracts (named in
//! `tests/gcode_oracle`): with G98 it feeds G84/G74/G89 out all the way to the initial Z, and
//! its G87 takes I J K with Z as the bottom; the reader follows Fanuc.

use crate::motion::program::{Block, Feed, Motion, Pose};

#[cfg(test)]
mod tests;

/// Rapid clearance between pecks (G73: back-off; G83: above the last depth), mm.
pub(crate) const PECK_CLEARANCE_MM: f64 = 0.254;

/// A canned cycle in force (modal until G80 or a G0..G3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Cycle {
    /// G code (73, 74, 81..89).
    pub code: u32,
    /// Z of the initial level (where the cycle began), mm, machine frame.
    pub initial_z_mm: f64,
    /// Z of the R plane, mm, machine frame.
    pub r_z_mm: f64,
    /// Z of the hole bottom (G87: the top of the back bore), mm, machine frame.
    pub bottom_z_mm: f64,
    /// Dwell at the bottom (G74 G82 G84 G88 G89), s.
    pub dwell_s: f64,
    /// Peck depth Q of G73/G83, mm (None: fed straight to Z).
    pub peck_mm: Option<f64>,
}

/// What the reader cannot model of a cycle code (a warning; refused under `strict`), or None
/// when the expansion above is the whole cycle.
pub(crate) fn unmodelled(code: u32) -> Option<&'static str> {
    Some(match code {
        73 | 83 => {
            "pecks of Q with a 0.254 mm rapid clearance between them (LinuxCNC's value; on a \
             Fanuc control parameters 5114/5115)"
        }
        74 | 84 => {
            "tapping: fed in and out along Z at F (F = S x pitch under G94); the spindle \
             reversal at the bottom is not modelled"
        }
        86 => "boring: the spindle stop at the bottom is not modelled; rapid out",
        87 => {
            "back boring (Fanuc): rapid down to R below the part, feed up to Z, rapid to the \
             initial level; the oriented-spindle shift Q is not modelled"
        }
        88 => {
            "boring with a manual retract: after the dwell the path rapids out as on cycle \
             start; the manual jog is not modelled"
        }
        _ => return None,
    })
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
        if p.xyz[2] < self.r_z_mm {
            // Below the R plane: up to it before moving across (LinuxCNC's preliminary
            // motion; moving across below R could run the tool into the part).
            p.xyz[2] = self.r_z_mm;
            path.go(p, Motion::Linear, Feed::Rapid);
        }
        p.xyz[0] = xy[0];
        p.xyz[1] = xy[1];
        path.go(p, Motion::Linear, Feed::Rapid);
        // Rapid down (or up) to R, feed to the bottom.
        p.xyz[2] = self.r_z_mm;
        path.go(p, Motion::Linear, Feed::Rapid);
        if let (73 | 83, Some(q)) = (self.code, self.peck_mm) {
            // As LinuxCNC counts them: depths R - q, R - 2q, ... while above the bottom (by
            // more than rounding: when Z - R is a whole number of pecks the last one is Z).
            let mut depth = self.r_z_mm - q;
            while depth > self.bottom_z_mm + 1e-9 {
                p.xyz[2] = depth;
                path.go(p, Motion::Linear, feed);
                if self.code == 83 {
                    p.xyz[2] = self.r_z_mm;
                    path.go(p, Motion::Linear, Feed::Rapid);
                }
                p.xyz[2] = depth + PECK_CLEARANCE_MM;
                path.go(p, Motion::Linear, Feed::Rapid);
                depth -= q;
            }
        }
        p.xyz[2] = self.bottom_z_mm;
        path.go(p, Motion::Linear, feed);
        if matches!(self.code, 74 | 82 | 84 | 88 | 89) && self.dwell_s > 0.0 {
            let seconds = self.dwell_s;
            path.go(p, Motion::Dwell { seconds }, Feed::Rapid);
        }
        let back = match self.code {
            74 | 84 | 85 | 89 => Some(feed),
            87 => None,
            _ => Some(Feed::Rapid),
        };
        let up_to_initial = (to_initial || self.code == 87) && self.initial_z_mm > self.r_z_mm;
        match back {
            // A rapid out goes straight on to the initial level under G98 (one move, as
            // LinuxCNC makes it).
            Some(Feed::Rapid) if up_to_initial => {}
            Some(back) => {
                p.xyz[2] = self.r_z_mm;
                path.go(p, Motion::Linear, back);
            }
            None => {}
        }
        // G87 always returns to the initial level (Fanuc: G99 is not used with it).
        if (to_initial || self.code == 87) && self.initial_z_mm > p.xyz[2] {
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
