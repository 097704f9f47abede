//! Compensated programs for CAM post-processors (CONTRACT v1.1 "Compensated programs"):
//! volumetric pre-compensation of a G-code program against the machine's error map, written
//! back keeping the post's structure, and of plain CL points.
//!
//! Files: `field` (the error field: the volumetric map), `paths` (compensated lines and arcs,
//! split into G1 points within the tolerance), `emit` (re-emission: axis words replaced in
//! the program's own units and G90/G91 mode, a motion line replaceable by G1 points),
//! `program` (the whole program), `points` (the points form, JSON or CSV), `error`.
//! `predistort` (contour-error pre-compensation) chooses slowed stretches and moved points
//! at corners and corrected radii of arcs, which the emitter writes through
//! [`LinePlan::Points`] and [`LinePlan::Arcs`] (module `contour`).

mod contour;
mod emit;
mod error;
mod field;
pub(crate) mod paths;
mod points;
pub mod predistort;
pub(crate) mod program;
pub mod reversals;
#[cfg(test)]
mod tests;

pub use contour::{
    MAX_ITERATIONS, contour_program, corrected_and_contour, judge_written, line_end_times,
    volumetric_and_contour,
};
pub use emit::{Emitter, LineInfo, LinePlan, decimals, format_number, rewrite, rounding_mm};
pub use error::Error;
pub use field::{ErrorField, SumField};
pub use paths::{Shifter, SubArc, arc_pieces, arc_point, linear_points, sub_arc};
pub use points::{CompensatedPoints, compensate_points, points_from_csv, points_to_csv};
pub use predistort::{
    DEFAULT_BAND_MM, DEFAULT_MAX_DURATION_RATIO, ErrorStats, MAX_DURATION_RATIO, MaterialSide,
    ModelFigures, Piece, PredistortOptions, Predistorted, predistort, predistort_sided,
};
pub use program::{
    Compensated, DEFAULT_TOLERANCE_MM, MAX_OUTPUT_BLOCKS, MAX_TOLERANCE_MM, MIN_TOLERANCE_MM,
    Offsets, check_tolerance, compensate_program, compensate_with_offsets,
};
