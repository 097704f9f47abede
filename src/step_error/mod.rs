//! Step error of ball-end finishing as a capability: flat segment batches solved exactly on
//! all cores, and the network that predicts the step error (training, fine-tuning, the model
//! file's metadata). Uses the `geometry` core (the exact route, features) and `nn` (the
//! network); knows nothing of HTTP, so the server, the CLI and the benchmarks call it alike.
//! Reference: Zhang et al. 2023 eq. 1, as `geometry::step_error`.

mod batch;
mod error;
mod model;
pub mod surfaces;
mod train;
pub mod transfer;

#[cfg(test)]
mod tests;

pub use batch::{SegmentBatch, SegmentsBody, solve_batch};
pub use error::{Error, Result};
pub use model::{META_VERSION, MODEL_KIND, ModelMeta, Prediction, model_features, predict_um};
pub use train::TrainJob;
