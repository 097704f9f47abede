//! Response side of the volumetric-map resource: the map summary (GET and PUT) and the
//! predict body.

use serde::Serialize;
use serde_json::json;

use crate::volumetric::{self, ResidualKind, VolumetricMap};

pub(super) fn summary(map: &VolumetricMap) -> serde_json::Value {
    // which residual part a hybrid carries (null for the other models)
    let residual = match &map.model {
        volumetric::Model::Hybrid(h) => match h.residual_kind() {
            ResidualKind::Spline => Some("spline"),
            ResidualKind::Network => Some("network"),
        },
        _ => None,
    };
    // how the ISO 230-1 error motions are represented (the kinematic part, when fitted)
    let error_motions = map.components.as_ref().map(|k| {
        json!({
            "basis": k.basis,
            "terms_per_axis": k.degree.map(|d| d + 1),
            "smoothing": k.smoothing,
            "effective_parameters": k.effective_parameters,
        })
    });
    json!({
        "model": map.model.kind().name(),
        "residual": residual,
        "error_motions": error_motions,
        "requested": map.options.model.name(),
        "parameter_count": map.model.parameter_count(),
        "n_nodes": map.n_nodes,
        "cv_scheme": map.cv_scheme,
        "scores": map.scores,
        "fit_rms_mm": map.fit_rms_mm,
        "bounds": map.bounds,
        "tool_offset_mm": map.options.tool_offset_mm,
        "units": {"lengths": "mm", "errors": "mm", "cv_rms_mm": "mm"},
        "truecut_version": map.truecut_version,
    })
}

#[derive(Debug, Serialize)]
pub(super) struct PredictResponse {
    pub(super) errors: Vec<[f64; 3]>,
    pub(super) out_of_box: Vec<bool>,
    pub(super) model: &'static str,
}
