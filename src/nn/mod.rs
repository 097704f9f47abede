//! Small dense neural networks (multi-layer perceptrons) on nalgebra: layers, activations,
//! initialisation, z-score scaling, dropout, SGD-momentum / Adam, early stopping, a compact
//! binary file format. Used by the step-error network (Zhang et al. 2023) and the volumetric maps
//! (Xiang et al. 2019 and Wang, Dai & Hong).
//!
//! Written here rather than taken from a crate: candle lacks SGD momentum, burn takes minutes
//! to build, and the networks are tiny (tens of neurons), so a few hundred lines suffice.

mod activation;
mod data;
mod error;
mod fast;
mod format;
mod init;
mod mlp;
mod optimizer;
mod regressor;
mod scaler;
mod train;

pub use activation::Activation;
pub use data::{gather_rows, split_indices};
pub use error::Error;
pub use format::FORMAT_VERSION;
pub use init::Init;
pub use mlp::Mlp;
pub use optimizer::{LrSchedule, Optimizer};
pub use regressor::Regressor;
pub use scaler::ZScore;
pub use train::{EpochStats, TrainConfig, TrainReport, train};
