//! What a trained step-error network carries beside its weights, and how to read it back.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::error::{Error, Result};
use crate::geometry::{StepFeatures, StepInputs};
use crate::nn::Regressor;

/// Model kind under which the network is stored per machine and surface.
pub const MODEL_KIND: &str = "step_error_nn";

/// Version of [`ModelMeta`] this build writes and the newest it reads. 1: coordinate inputs
/// only (no `version` and no `features.inputs` in the file: such models load with the
/// coordinates they were trained on). 2: `features.inputs` names the inputs; the default is
/// the distance profile ([`StepInputs::Profile`]).
pub const META_VERSION: u32 = 2;

fn version_1() -> u32 {
    1
}

/// What is stored beside the weights (the model file's metadata, JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelMeta {
    /// Always [`MODEL_KIND`].
    pub kind: String,
    /// Metadata version ([`META_VERSION`] when written by this build; 1 when absent).
    #[serde(default = "version_1")]
    pub version: u32,
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
    /// model's, [`Error::NewerModel`] if a newer truecut wrote it). Version 1 files (no
    /// `version`, no `features.inputs`) read as coordinate inputs, which is what they were
    /// trained on.
    pub fn of(reg: &Regressor) -> Result<ModelMeta> {
        let meta: ModelMeta =
            serde_json::from_str(&reg.metadata).map_err(|e| Error::Metadata(e.to_string()))?;
        if meta.version > META_VERSION {
            return Err(Error::NewerModel {
                version: meta.version,
                supported: META_VERSION,
            });
        }
        if meta.features.len() != reg.n_inputs() || meta.features.n_outputs() != reg.n_outputs() {
            return Err(Error::Metadata(format!(
                "the features describe {} inputs and {} outputs but the network has {} and {}",
                meta.features.len(),
                meta.features.n_outputs(),
                reg.n_inputs(),
                reg.n_outputs()
            )));
        }
        Ok(meta)
    }
}

/// Decodes a model file's metadata: (features, training tool radius in mm).
pub fn model_features(reg: &Regressor) -> Result<(StepFeatures, f64)> {
    let meta = ModelMeta::of(reg)?;
    Ok((meta.features, meta.tool_radius_mm))
}

/// What [`predict_um`] answers.
#[derive(Clone, Debug)]
pub struct Prediction {
    /// Predicted step error per segment, µm.
    pub um: Vec<f64>,
    /// With profile inputs, the m samples' own estimate per segment (µm,
    /// [`StepFeatures::knot_estimate`]), to show what the network adds.
    pub knot_um: Option<Vec<f64>>,
    /// The network's input rows (row-major, `f.len()` columns), e.g. to tell which segments
    /// lie outside the trained range.
    pub inputs: Vec<f64>,
}

/// Step errors (µm) of `segments` (CL points, CC points) predicted by the network `reg` reading
/// features `f` with ball radius `tool_radius_mm`: the feature rows, the network on all cores,
/// then [`StepFeatures::combine`]. Also the m samples' own estimate (µm,
/// [`StepFeatures::knot_estimate`]) with profile inputs, and the input rows.
/// Errors name the first bad segment.
pub fn predict_um<'a>(
    reg: &Regressor,
    f: &StepFeatures,
    tool_radius_mm: f64,
    segments: impl ExactSizeIterator<Item = ([[f64; 3]; 2], &'a [[f64; 3]])>,
) -> Result<Prediction> {
    let (x, info) = f.matrix(tool_radius_mm, segments)?;
    let y = reg.predict_parallel(&x, 0)?;
    let knot_um = (f.inputs == StepInputs::Profile).then(|| StepFeatures::knot_estimate(&info));
    Ok(Prediction {
        um: f.combine(&y, &info),
        knot_um,
        inputs: x,
    })
}
