//! Exact step error of 3-axis ball-end finishing between two cutter locations (Zhang et al. 2023
//! eq. 1): the solver one segment at a time and in batches ([`solver`]), its lane-parallel
//! kernel ([`lanes`]), the input check alone ([`check_segment`]), and the oracle tests against the Python study's vectors.

mod check;
mod lanes;
mod solver;

pub use check::check_segment;
pub use solver::*;

#[cfg(test)]
mod tests;
