//! The one error type of the `step_error` core.

use crate::{geometry, nn};

/// Everything that can go wrong labelling, training or reading a step-error model. Variants
/// name what to fix, so `api` maps them to statuses without rewording.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A segment or the feature choice is unusable (the geometry core says which).
    #[error(transparent)]
    Geometry(#[from] geometry::Error),
    /// The network could not be built, trained or run (the nn core says why).
    #[error(transparent)]
    Nn(#[from] nn::Error),
    /// The held-out split left no training or no validation samples.
    #[error("too few segments to split into training and validation parts: send more")]
    TooFewToSplit,
    /// A model file's metadata is not a step-error model's (written by another program or a
    /// bug): nothing the caller can fix.
    #[error("the step-error model metadata is unreadable: {0}")]
    Metadata(String),
    /// The model file was written by a newer truecut whose inputs this build does not know.
    #[error(
        "the step-error model has metadata version {version} but this build reads versions up to {supported}: retrain the model with this build, or upgrade truecut"
    )]
    NewerModel {
        /// Version in the file.
        version: u32,
        /// Newest version this build reads.
        supported: u32,
    },
    /// The caller's progress callback asked to stop (the job was cancelled).
    #[error("the training was cancelled")]
    Cancelled,
}

/// Result type of the `step_error` core.
pub type Result<T> = std::result::Result<T, Error>;
