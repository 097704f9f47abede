//! What a pre-distortion may do ([`PredistortOptions`]) and the check of its ranges.

use super::Error;

/// What the pre-distortion may do.
#[derive(Clone, Debug, PartialEq)]
pub struct PredistortOptions {
    /// Interpolation period of the simulation, s (1e-5..0.1).
    pub period_s: f64,
    /// Most optimiser iterations (Jacobians; each simulates the model set a few times per
    /// feature colour), 0..=100; 0 writes the program unchanged.
    pub max_iterations: usize,
    /// Longest duration of the compensated program, as a multiple of the original's
    /// (1..=2; [`DEFAULT_MAX_DURATION_RATIO`] = 1.15, issue 24's gate): the slowed stretches
    /// at corners fit within it; a larger ratio trades cycle time for a smaller contour
    /// error where corners follow each other closely.
    pub max_duration_ratio: f64,
    /// Half-width of the tolerance band about the original path, mm
    /// ([`DEFAULT_BAND_MM`] by default; within [`BAND_RANGE_MM`]): the simulated tool may
    /// leave the path by at most this much towards the material (on both sides where the
    /// program does not say the material side with G41/G42), or by what the original
    /// already did there.
    pub band_mm: f64,
}

/// Default [`PredistortOptions::band_mm`]: 10 µm, a finishing tolerance.
pub const DEFAULT_BAND_MM: f64 = 0.01;

/// Accepted range of [`PredistortOptions::band_mm`], mm.
pub const BAND_RANGE_MM: std::ops::RangeInclusive<f64> = 0.001..=1.0;

/// Default [`PredistortOptions::max_duration_ratio`]: the compensated program may take up
/// to 1.15 times the original's duration (issue 24).
pub const DEFAULT_MAX_DURATION_RATIO: f64 = 1.15;

/// Largest [`PredistortOptions::max_duration_ratio`] accepted.
pub const MAX_DURATION_RATIO: f64 = 2.0;

impl PredistortOptions {
    /// [`Error::Option`] naming the first option out of its range: `period_s` within
    /// 1e-5..0.1 s, `max_duration_ratio` within 1..[`MAX_DURATION_RATIO`], `band_mm` within
    /// [`BAND_RANGE_MM`], `max_iterations`
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
        if !(self.band_mm.is_finite() && BAND_RANGE_MM.contains(&self.band_mm)) {
            return Err(Error::Option {
                field: "band_mm",
                message: format!(
                    "must be within {}..{} mm (the tolerance band about the path), got {}",
                    BAND_RANGE_MM.start(),
                    BAND_RANGE_MM.end(),
                    self.band_mm
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
