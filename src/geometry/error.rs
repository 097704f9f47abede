//! The one error type of the `geometry` core.

/// Bad geometric input or a degenerate configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Too few points for the operation.
    #[error("{what} needs at least {min} points, got {got}")]
    TooFewPoints {
        /// Which curve or array.
        what: &'static str,
        /// Minimum needed.
        min: usize,
        /// Number received.
        got: usize,
    },
    /// NaN or infinity in an input.
    #[error("{field} holds a non-finite value at index {index}")]
    NonFinite {
        /// Which input.
        field: &'static str,
        /// Index of the first bad value.
        index: usize,
    },
    /// A value outside its valid range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name (with unit).
        name: &'static str,
        /// Value received.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// Two consecutive curve points coincide, so the curve has no direction there.
    #[error("points {index} and {} coincide: drop duplicate points", index + 1)]
    DuplicatePoints {
        /// Index of the first of the two points.
        index: usize,
    },
    /// The two cutter-location points coincide: the step has no direction.
    #[error("cl[0] and cl[1] coincide: a segment needs two distinct ball centres")]
    ZeroLengthStep,
    /// A cutter-location point that is not `tool_radius` away from its contact point.
    #[error(
        "cl[{end}] is {distance_mm} mm from its contact point but tool_radius is {tool_radius_mm} mm: \
         cl must be cc + tool_radius * unit normal (cc in feed order, first and last included)"
    )]
    InconsistentRadius {
        /// 0 for the first CL/CC pair, 1 for the last.
        end: usize,
        /// Distance |cl - cc| found, mm.
        distance_mm: f64,
        /// Tool radius given, mm.
        tool_radius_mm: f64,
    },
    /// Array lengths that do not fit together.
    #[error("{what}: expected {expected}, got {got}")]
    Shape {
        /// Which array.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Received length.
        got: usize,
    },
    /// An error in one segment of a batch.
    #[error("segment {index}: {source}")]
    InSegment {
        /// Index of the segment in the batch.
        index: usize,
        /// What is wrong with it.
        source: Box<Error>,
    },
}

/// Result alias of the `geometry` core.
pub type Result<T> = std::result::Result<T, Error>;

pub(crate) fn check_points(field: &'static str, pts: &[[f64; 3]]) -> Result<()> {
    match pts.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        Some(index) => Err(Error::NonFinite { field, index }),
        None => Ok(()),
    }
}
