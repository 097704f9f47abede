//! The one error type of the `gap` core.

/// Everything that can go wrong in a gap diagnosis; every variant says which field to fix.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// The servo model of the machine is invalid (wraps the motion core's sentence).
    #[error("servo model of axis {axis}: {source}")]
    Servo {
        /// Axis letter ("X", "Y", "Z").
        axis: String,
        /// The motion core's error.
        #[source]
        source: crate::motion::Error,
    },
    /// A field has the wrong shape (lengths, dimensions, too few samples).
    #[error("{field}: {reason}")]
    Shape {
        /// JSON field name, e.g. "measured".
        field: String,
        /// What is wrong and how to fix it.
        reason: String,
    },
    /// A value is NaN or infinite.
    #[error("{field}[{index}] is not a finite number")]
    NonFinite {
        /// JSON field name.
        field: String,
        /// Index of the first bad row/value.
        index: usize,
    },
    /// A scalar parameter is out of range.
    #[error("{field} = {value} is invalid: {reason}")]
    Invalid {
        /// JSON field name.
        field: String,
        /// The offending value.
        value: f64,
        /// What to fix.
        reason: String,
    },
}

impl Error {
    pub(crate) fn shape(field: &str, reason: impl Into<String>) -> Self {
        Self::Shape {
            field: field.to_string(),
            reason: reason.into(),
        }
    }
}
