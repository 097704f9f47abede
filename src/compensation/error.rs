//! The one error type of the compensation core.

/// Why a compensation could not be computed; each sentence names the input to fix.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// Arrays that must have one entry per grid point do not.
    #[error("{field} has {got} entries but the grid has {expected} points (nu*nv)")]
    LengthMismatch {
        /// Name of the array in the request.
        field: &'static str,
        /// Entries it has.
        got: usize,
        /// Entries it must have (nu*nv).
        expected: usize,
    },
    /// A value is NaN or infinite.
    #[error("{field}[{index}] is not finite")]
    NonFinite {
        /// Name of the array in the request.
        field: &'static str,
        /// Index of the first bad entry.
        index: usize,
    },
    /// A normal of (near) zero length.
    #[error("normals[{index}] has zero length; normals must be unit vectors")]
    ZeroNormal {
        /// Index of the grid point whose normal is zero.
        index: usize,
    },
    /// A grid or density too small or too large.
    #[error("{field} = {got} is out of range: {reason}")]
    BadSize {
        /// Name of the size parameter.
        field: &'static str,
        /// Value sent.
        got: usize,
        /// The allowed range, as a sentence.
        reason: &'static str,
    },
    /// A negative or non-finite tool radius.
    #[error("tool_radius must be a finite number >= 0 mm")]
    BadToolRadius,
}
