//! The one error type of the `nn` core.

/// Everything that can go wrong when building, training, running or decoding a network.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Fewer than two layer sizes (an input and an output layer are needed).
    #[error("a network needs at least an input and an output layer size, got {0} size(s)")]
    TooFewLayers(usize),
    /// A layer of zero neurons.
    #[error("layer {index} has 0 neurons; every layer needs at least one")]
    EmptyLayer {
        /// Position of the layer (0 = input).
        index: usize,
    },
    /// An array of the wrong length.
    #[error("{what}: expected {expected} values, got {got}")]
    Shape {
        /// Which array.
        what: &'static str,
        /// Expected number of values.
        expected: usize,
        /// Number received.
        got: usize,
    },
    /// Not enough samples for the requested operation.
    #[error("{what} needs at least {min} samples, got {got}")]
    TooFewSamples {
        /// Which operation.
        what: &'static str,
        /// Minimum needed.
        min: usize,
        /// Number received.
        got: usize,
    },
    /// NaN or infinity in an input array.
    #[error("{field} holds a non-finite value at index {index}")]
    NonFinite {
        /// Which array.
        field: &'static str,
        /// Flat index of the first bad value.
        index: usize,
    },
    /// A hyper-parameter outside its valid range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Value received.
        value: f64,
        /// What the valid range is.
        reason: &'static str,
    },
    /// The loss became NaN or infinite during training.
    #[error("training diverged at epoch {epoch} (loss is not finite): lower the learning rate")]
    Diverged {
        /// Epoch (1-based) at which it happened.
        epoch: usize,
    },
    /// A model file that cannot be decoded.
    #[error("model file: {0}")]
    Format(String),
    /// Two models (or a model and data) that do not fit together.
    #[error("incompatible model: {0}")]
    Incompatible(String),
}

/// Result alias of the `nn` core.
pub type Result<T> = std::result::Result<T, Error>;

/// Index of the first non-finite value, as an [`Error::NonFinite`].
pub(crate) fn check_finite(field: &'static str, xs: &[f64]) -> Result<()> {
    match xs.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFinite { field, index }),
        None => Ok(()),
    }
}
