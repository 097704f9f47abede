//! Exact step error of 3-axis ball-end finishing between two cutter locations (Zhang et al. 2023
//! eq. 1): the solver one segment at a time and in batches ([`solver`]), its lane-parallel
//! kernel ([`lanes`]), and the oracle tests against the Python study's vectors.

mod lanes;
mod solver;

pub use solver::*;

#[cfg(test)]
mod tests;
