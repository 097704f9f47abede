//! The `cam` core's one error type.

use crate::motion;

/// Everything that can go wrong while compensating a program or a list of points. Each
/// message names the field and the fix.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// The program could not be read (names the line and the word; 422 over HTTP).
    #[error(transparent)]
    Read(#[from] motion::Error),
    /// `tolerance_mm` outside its range.
    #[error("tolerance_mm must be between {min} and {max} mm, got {got}")]
    Tolerance {
        /// The value sent, mm.
        got: f64,
        /// Smallest allowed, mm.
        min: f64,
        /// Largest allowed, mm.
        max: f64,
    },
    /// A NaN or infinite coordinate.
    #[error("'{field}[{index}]' is not a finite number")]
    NonFinite {
        /// Name of the array in the request.
        field: &'static str,
        /// Index of the first bad entry.
        index: usize,
    },
    /// An array that needs entries is empty.
    #[error("'{field}' is empty: send at least one point")]
    Empty {
        /// Name of the array in the request.
        field: &'static str,
    },
    /// A CSV body could not be read.
    #[error("CSV line {line}: {reason}")]
    Csv {
        /// 1-based line of the CSV body.
        line: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// Splitting would make the answer longer than the service writes.
    #[error(
        "the compensated program would exceed {limit} blocks: raise tolerance_mm or send the program in parts"
    )]
    TooLong {
        /// Most blocks written.
        limit: usize,
    },
    /// The contour pre-distortion could not be made (names the line or the option).
    #[error(transparent)]
    Contour(#[from] super::predistort::Error),
}
