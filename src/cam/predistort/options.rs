//! What a pre-distortion may do ([`PredistortOptions`]) and the check of its ranges.

use super::Error;

/// What the pre-distortion may do.
#[derive(Clone, Debug, PartialEq)]
pub struct PredistortOptions {
    /// Interpolation period of the simulation, s (1e-5..0.1).
    pub period_s: f64,
    /// Most pre-distortion iterations (each one interpolation and simulation), 0..=100.
    pub max_iterations: usize,
    /// Longest duration of the compensated program, as a multiple of the original's
    /// (1..=2; [`DEFAULT_MAX_DURATION_RATIO`] = 1.15, issue 24's gate). The corner stages
    /// slow the corners the junction limit already slows (longer braking, stops at inside
    /// corners) within it: a larger ratio trades cycle time for a smaller contour error where
    /// corners follow each other closely.
    pub max_duration_ratio: f64,
}

/// Default [`PredistortOptions::max_duration_ratio`]: the compensated program may take up
/// to 1.15 times the original's duration (issue 24).
pub const DEFAULT_MAX_DURATION_RATIO: f64 = 1.15;

/// Largest [`PredistortOptions::max_duration_ratio`] accepted.
pub const MAX_DURATION_RATIO: f64 = 2.0;

impl PredistortOptions {
    /// [`Error::Option`] naming the first option out of its range: `period_s` within
    /// 1e-5..0.1 s, `max_duration_ratio` within 1..[`MAX_DURATION_RATIO`], `max_iterations`
    /// at most 100.
    pub fn check(&self) -> Result<(), Error> {
        if !(self.period_s.is_finite() && (1e-5..=0.1).contains(&self.period_s)) {
            return Err(Error::Option {
                field: "period_s",
                message: format!("must be within 1e-5..0.1 s, got {}", self.period_s),
            });
        }
        if !(self.max_duration_ratio.is_finite()
            && (1.0..=MAX_DURATION_RATIO).contains(&self.max_duration_ratio))
        {
            return Err(Error::Option {
                field: "max_duration_ratio",
                message: format!(
                    "must be within 1..{MAX_DURATION_RATIO} (the compensated program's duration over \
                     the original's), got {}",
                    self.max_duration_ratio
                ),
            });
        }
        if self.max_iterations > 100 {
            return Err(Error::Option {
                field: "max_iterations",
                message: format!("must be within 0..=100, got {}", self.max_iterations),
            });
        }
        Ok(())
    }
}
