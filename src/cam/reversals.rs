//! Backlash corrected in a program (issue 40 item 2): the table of an axis with play b lags
//! its motor by b/2 against the direction the axis last moved (the diagnosis' play operator,
//! the table in contact). So every point written after the axis moved in direction d is
//! commanded b/2·d further ([`Reversals::bias`]), and where d changes (a reversal, or the
//! axis' first move), a take-up move of the change alone is written before the move goes on:
//! the motor crosses the gap while the table stands, as a controller's backlash compensation
//! steps its command at a reversal. Arcs are split at the points where an axis of their plane
//! reverses, with the take-up between the sub-arcs.
//!
//! A rapid takes its direction but needs no take-up (it cuts nothing). A move the controller
//! needs whole (cutter compensation) gets no take-up: its ends carry the offsets, so the gap
//! is crossed along it. Canned cycles are written without backlash offsets.

/// The backlash state of a program being written: the play per axis and each axis' last
/// direction of motion.
#[derive(Clone, Debug, PartialEq)]
pub struct Reversals {
    /// Play per axis (X, Y, Z), mm; 0: none.
    width_mm: [f64; 3],
    /// Last direction per axis (−1, +1; 0 before its first move).
    dir: [f64; 3],
}

/// A motion of an axis shorter than this (1 nm) is no motion: it neither reverses the axis
/// nor takes up its play.
pub const STILL_MM: f64 = 1e-6;

impl Reversals {
    /// No axis has moved yet; `width_mm` is the play per axis (X, Y, Z), mm.
    pub fn new(width_mm: [f64; 3]) -> Self {
        Reversals {
            width_mm,
            dir: [0.0; 3],
        }
    }

    /// Whether any axis has play.
    pub fn any(&self) -> bool {
        self.width_mm.iter().any(|&b| b > 0.0)
    }

    /// The offset (mm) added to every point written now: b/2 along each axis' last
    /// direction.
    pub fn bias(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| 0.5 * self.width_mm[k] * self.dir[k])
    }

    /// The axes move by `moved` (mm, or only its signs): each axis with play that moves
    /// takes its direction. Returns whether one of them changed direction (a reversal, or
    /// its first move): the bias changed and a take-up is due.
    pub fn turn(&mut self, moved: [f64; 3]) -> bool {
        let mut changed = false;
        for ((dir, &b), &m) in self.dir.iter_mut().zip(&self.width_mm).zip(&moved) {
            if b > 0.0 && m.abs() > STILL_MM {
                changed |= m.signum() != *dir;
                *dir = m.signum();
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests;
