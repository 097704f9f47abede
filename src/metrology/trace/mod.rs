//! ISO 230-2 from a logged positioning run, as drives really log it: the command and the laser
//! (or scale) reading, sampled every `period_s`. The service reads what an operator reads off
//! the plot, and takes the time of each reading from the *measured* motion, never from the
//! command's: a drive logs the command as the target itself, written when the move starts, so
//! the command already equals the target while a slow axis is still travelling (a reader that
//! averaged the command's hold read −1.4 mm forward and +1.4 mm backward on such a log), and a
//! measuring device with its own sample clock drifts against the command's sample index.
//!
//! 1. **Commanded approaches** (`Visit`): runs where the command holds one position for at
//!    least `min_dwell_s`; positions within `target_tolerance_mm` are one. The direction of an
//!    approach is the sign of the last command motion before it, so a target approached
//!    through an overrun and a reversal (ISO 230-2:2014 §5.3.2, the linear cycle) counts in the
//!    direction of its final approach.
//! 2. **Targets**: positions approached at least twice from each direction; the start point
//!    and the overrun (turnaround) points are approached from one side and are not targets.
//! 3. **Settled stops** of the measured position (`settle.rs`): samples where the speed over a
//!    window of `min_settled_s` centred on them is at most `settle_speed_mm_s`; the reading is
//!    the mean over the stop's settled *end*, its last window before the axis moves again
//!    (a slowly settling axis is still creeping in when it first moves slower than the
//!    threshold: 10 µm short at 10 µm/s with a 1 s time constant).
//! 4. **Matching** (`matching.rs`): stops and approaches in time order, by position only (less
//!    the measuring device's constant offset, found as the shift that puts the most stops on
//!    commanded positions). The offset is reported and kept in the readings: a constant shifts
//!    every mean deviation x̄ alike and leaves A, E, M, R and B unchanged (each is a range, a
//!    difference or a spread of the x̄ and the readings).
//! 5. **Refusal**: a target with fewer readings in a direction than the command's approaches
//!    in that direction (the cycles) is refused, naming the target and the direction.
//!
//! Every reading used (with its settled window) and every stop not used is reported, so the
//! caller can check the choice on the plot. Written here: no crate reads machine-tool
//! positioning logs.

mod matching;
mod read;
mod settle;
#[cfg(test)]
mod simlog;
#[cfg(test)]
mod tests;

pub use matching::{Visit, device_offset, match_stops, match_tolerance, visits_by_position};
pub use read::{
    MAX_TARGETS, PositioningTrace, Settling, TraceEvaluation, TraceOptions, TraceReading,
    evaluate_trace, find_visits,
};
pub use settle::{SAME_STOP_MM, SettledRun, merge_stops, settled_runs};
