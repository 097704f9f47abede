//! How the controller ends each block of a program, as the program's path-control codes ask
//! ([`PathControl`]): the reader fills it ([`super::gcode::parse_modes`]), the interpolator
//! applies it (`super::interpolate::modes`).
//!
//! Kept beside the program rather than in [`super::program::Block`] so that code building
//! blocks by hand (the compensated-program planner) is unchanged: a program without a
//! [`PathControl`] runs as it always did, every junction in the service's own look-ahead.
//!
//! | program | block end |
//! |---|---|
//! | G64 (no P, or P0), G05.1 Q1, G08 P1 | [`BlockEnd::Continuous`]: the service's look-ahead |
//! | G64 P*tol* | [`BlockEnd::Blend`]: corners rounded within *tol* (LinuxCNC) |
//! | G61, G61.1, G9 (one block), G05.1 Q0, G08 P0 | [`BlockEnd::Stop`]: the speed reaches 0 |

use std::collections::BTreeMap;

/// What the controller does at the end of one block.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum BlockEnd {
    /// G64 without a tolerance: the junction speed of the service's look-ahead.
    #[default]
    Continuous,
    /// G64 P: LinuxCNC's blending; the path may leave the programmed corner by at most
    /// `tolerance_mm` (mm, after G20 conversion).
    Blend {
        /// The P word in mm.
        tolerance_mm: f64,
    },
    /// Exact stop: the commanded speed reaches 0 at the block's end point.
    Stop,
}

/// The end of every block of a program, keyed by the block's source line (all blocks of a
/// line, e.g. a canned cycle's, share its end rule). Lines absent are
/// [`BlockEnd::Continuous`]; an empty table is a program without path-control codes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PathControl {
    ends: BTreeMap<usize, BlockEnd>,
}

impl PathControl {
    /// The end rule of the blocks of 1-based source `line`.
    pub fn end_of(&self, line: usize) -> BlockEnd {
        self.ends.get(&line).copied().unwrap_or_default()
    }

    /// Sets the end rule of the blocks of `line` (a continuous end is not stored).
    pub fn set(&mut self, line: usize, end: BlockEnd) {
        if end == BlockEnd::Continuous {
            self.ends.remove(&line);
        } else {
            self.ends.insert(line, end);
        }
    }

    /// True when every block ends in the service's own look-ahead.
    pub fn is_continuous(&self) -> bool {
        self.ends.is_empty()
    }
}
