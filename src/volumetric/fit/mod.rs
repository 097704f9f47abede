//! Fitting a map: cross-validation on held-out nodes, the automatic choice, prediction.
//!
//! Files: `driver` (the options and [`fit`]: score the candidates, refit the chosen one),
//! `cv` (held-out node sets, cross-validated scores, the automatic choice) and `map` (the
//! fitted map: prediction, stored form, deviation along normals).

mod cv;
mod driver;
mod map;
#[cfg(test)]
mod tests;

pub use cv::{ModelScore, folds};
pub use driver::{FitOptions, fit};
pub use map::{Prediction, VolumetricMap, normal_deviation};
