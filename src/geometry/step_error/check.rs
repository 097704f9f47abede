//! The per-segment input check of the exact solver, on its own: the step-error network's
//! predictions take the same geometry as the exact route, so they share this check.

use super::solver::prepare;
use crate::geometry::error::Result;

/// Checks one segment as [`StepErrorSolver::solve`](super::StepErrorSolver::solve) does
/// before solving: a positive finite `tool_radius_mm`, at least three finite `cc` points, a
/// step of non-zero length between the two cutter locations `cl`, and both ends of the
/// `cc` curve at the tool radius (within 0.1 %) from their cutter location. Units: mm.
/// Costs a few dot products; computes nothing else.
pub fn check_segment(tool_radius_mm: f64, cl: [[f64; 3]; 2], cc: &[[f64; 3]]) -> Result<()> {
    prepare(tool_radius_mm, cl, cc).map(|_| ())
}
