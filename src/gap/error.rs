//! The one error type of the `gap` core.

/// Everything that can go wrong in a gap diagnosis; every variant says which field to fix.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// The effects stored with the machine cannot be added to the simulation, or a body of
    /// effects to store is malformed (the sentence names the effect, the key and the fix).
    #[error("{0}")]
    Effects(String),
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
    /// A diagnosis request is malformed (a missing field, a field of the other domain, rows
    /// that do not pair up); the sentence names the field and the fix.
    #[error("{0}")]
    Request(String),
    /// A block has more samples than a diagnosis accepts.
    #[error("{field} has {rows} rows: at most {max} samples a block")]
    TooManySamples {
        /// JSON field name.
        field: String,
        /// Rows sent.
        rows: usize,
        /// Most rows accepted.
        max: usize,
    },
    /// A time-stamped log cannot be put on the program's clock (too short, no motion, another
    /// program, an ambiguous repeat); the sentence says which and what to send instead.
    #[error("{0}")]
    Align(String),
    /// The machine has servo models for fewer axes than the rows have columns.
    #[error(
        "machine '{machine}' has servo models for [{}] but the rows have {dims} columns: \
         PUT /v1/machines/{machine} with axes {}",
        have.join(", "),
        ["X", "Y", "Z"][..*dims].join(", ")
    )]
    MissingAxes {
        /// Machine id.
        machine: String,
        /// The axes it has servo models for.
        have: Vec<String>,
        /// Columns of the rows.
        dims: usize,
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
