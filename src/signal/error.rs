//! The one error type of the signal core.

/// Why a decomposition could not be computed. Every variant names the input that is wrong
/// and what to change, so the API can pass the sentence on as a 4xx detail.
#[non_exhaustive]
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum Error {
    /// The signal (or a component) has too few samples for the requested method.
    #[error("signal has {got} samples; {method} needs at least {min}")]
    TooShort {
        /// The method that needs more samples (`vmd`, `emd`, ...).
        method: &'static str,
        /// Samples sent.
        got: usize,
        /// Fewest samples the method accepts.
        min: usize,
    },
    /// A sample is NaN or infinite.
    #[error("signal[{index}] is not a finite number; send finite values in mm")]
    NonFinite {
        /// Index of the first bad sample.
        index: usize,
    },
    /// A parameter is out of its range.
    #[error("parameter '{name}' is invalid: {reason}")]
    BadParam {
        /// Name of the parameter (as the API names it).
        name: &'static str,
        /// Its allowed range, as a sentence.
        reason: String,
    },
    /// The signal's magnitude is beyond what the decomposition's sums of squares can hold
    /// (a result came out non-finite).
    #[error(
        "the decomposition overflowed: the signal's largest |value| is {max_abs:e}; send the \
         machining error in mm (|value| well below 1e100)"
    )]
    Overflow {
        /// Largest |sample| sent.
        max_abs: f64,
    },
    /// An unknown wavelet name.
    #[error("unknown wavelet '{0}'; use db1..db10, haar or sym2..sym10")]
    UnknownWavelet(String),
    /// The grid shape does not match the number of samples.
    #[error("grid {nu} x {nv} does not match {n} samples; nu*nv must equal the signal length")]
    GridMismatch {
        /// Grid points along u.
        nu: usize,
        /// Grid points along v.
        nv: usize,
        /// Samples sent.
        n: usize,
    },
}

/// Checks that every sample is finite and that there are at least `min` samples.
pub(crate) fn check_signal(method: &'static str, x: &[f64], min: usize) -> Result<(), Error> {
    if x.len() < min {
        return Err(Error::TooShort {
            method,
            got: x.len(),
            min,
        });
    }
    if let Some(index) = x.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite { index });
    }
    Ok(())
}
