//! The one error type of the compensation core.

/// Why a compensation could not be computed; each sentence names the input to fix.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// Arrays that must have one entry per grid point do not.
    #[error("{field} has {got} entries but the grid has {expected} points (nu*nv)")]
    LengthMismatch {
        field: &'static str,
        got: usize,
        expected: usize,
    },
    /// A value is NaN or infinite.
    #[error("{field}[{index}] is not finite")]
    NonFinite { field: &'static str, index: usize },
    /// A normal of (near) zero length.
    #[error("normals[{index}] has zero length; normals must be unit vectors")]
    ZeroNormal { index: usize },
    /// A grid or density too small or too large.
    #[error("{field} = {got} is out of range: {reason}")]
    BadSize {
        field: &'static str,
        got: usize,
        reason: &'static str,
    },
    /// A negative or non-finite tool radius.
    #[error("tool_radius must be a finite number >= 0 mm")]
    BadToolRadius,
}
