//! What a trained step-error network carries beside its weights, and how to read it back.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::error::{Error, Result};
use crate::geometry::StepFeatures;
use crate::nn::Regressor;

/// Model kind under which the network is stored per machine and surface.
pub const MODEL_KIND: &str = "step_error_nn";

/// What is stored beside the weights (the model file's metadata, JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelMeta {
    /// Always [`MODEL_KIND`].
    pub kind: String,
    /// Network inputs and outputs.
    pub features: StepFeatures,
    /// Tool radius of the training samples, mm (the default radius of predictions).
    pub tool_radius_mm: f64,
    /// Hidden layer sizes.
    pub hidden: Vec<usize>,
    /// Unit of the network's outputs (`"um"`).
    pub output_unit: String,
    /// The training report (as answered by the training job).
    pub report: Value,
}

impl ModelMeta {
    /// Reads the metadata of a model file ([`Error::Metadata`] if it is not a step-error
    /// model's).
    pub fn of(reg: &Regressor) -> Result<ModelMeta> {
        serde_json::from_str(&reg.metadata).map_err(|e| Error::Metadata(e.to_string()))
    }
}

/// Decodes a model file's metadata: (features, training tool radius in mm).
pub fn model_features(reg: &Regressor) -> Result<(StepFeatures, f64)> {
    let meta = ModelMeta::of(reg)?;
    Ok((meta.features, meta.tool_radius_mm))
}
