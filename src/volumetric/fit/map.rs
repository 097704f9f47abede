//! A fitted volumetric error map with its validation record: prediction at query points,
//! the versioned stored form, and the deviation it adds along surface normals.

use super::cv::ModelScore;
use super::driver::FitOptions;
use crate::volumetric::Error;
use crate::volumetric::data::Bounds;
use crate::volumetric::kinematic::KinematicModel;
use crate::volumetric::model::Model;
use serde::{Deserialize, Serialize};

/// A fitted volumetric error map with its validation record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumetricMap {
    /// Format version of the serialised map.
    pub version: u32,
    /// The fitted model (the chosen one when `auto` was asked for).
    pub model: Model,
    /// Box of the measured nodes (mm); queries outside it are clamped and flagged.
    pub bounds: Bounds,
    /// Number of measured nodes fitted.
    pub n_nodes: usize,
    /// How the held-out nodes were chosen.
    pub cv_scheme: String,
    /// Cross-validated score of each model kind tried.
    pub scores: Vec<ModelScore>,
    /// RMS length of the residual at the nodes of the chosen model (mm).
    pub fit_rms_mm: f64,
    /// The ISO 230-1 fit used for the 21 component curves (whatever model predicts).
    pub components: Option<KinematicModel>,
    /// The options the map was fitted with.
    pub options: FitOptions,
    /// The version of truecut that fitted it, when the caller recorded it (the service does;
    /// maps saved before issue 25 have none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truecut_version: Option<String>,
}

/// Errors predicted at query points, with the points outside the measured box flagged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    /// `[dx, dy, dz]` (mm) per point.
    pub errors: Vec<[f64; 3]>,
    /// True where the point lies outside the measured box (its error is that of the
    /// nearest point of the box).
    pub out_of_box: Vec<bool>,
}

/// Version 2 (session 3): kinematic models name their error-motion basis (`spline` for new
/// fits); version-1 maps have none and are read as Legendre series, as they were written.
pub(super) const FORMAT_VERSION: u32 = 2;
/// Oldest map version this build still reads.
const OLDEST_READABLE: u32 = 1;

impl VolumetricMap {
    /// Predicted positioning errors (mm) at `points` (mm), flagging points outside the
    /// measured box (evaluated at the nearest point of the box). Errors: a non-finite
    /// coordinate.
    pub fn predict(&self, points: &[[f64; 3]]) -> Result<Prediction, Error> {
        if let Some(index) = points.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(Error::NonFinite {
                field: "points",
                index,
            });
        }
        Ok(Prediction {
            errors: self.model.eval_many(points),
            out_of_box: points.iter().map(|&p| !self.bounds.contains(p)).collect(),
        })
    }

    /// Predicted error vector (mm) at one point (mm), clamped into the box. For the
    /// part-domain gap diagnosis: the deviation a surface point gets from the machine
    /// is `error_at(p) · n` along the outward normal `n`. A non-finite point gives NaN.
    pub fn error_at(&self, point: [f64; 3]) -> [f64; 3] {
        if point.iter().any(|v| !v.is_finite()) {
            return [f64::NAN; 3];
        }
        self.model.eval_many(&[point])[0]
    }

    /// Serialised map (JSON, versioned) for the model store.
    pub fn to_bytes(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }

    /// Decodes [`VolumetricMap::to_bytes`]. Errors: not a map, or another version.
    pub fn from_bytes(bytes: &[u8]) -> Result<VolumetricMap, Error> {
        let m: VolumetricMap =
            serde_json::from_slice(bytes).map_err(|e| Error::ModelFormat(e.to_string()))?;
        if !(OLDEST_READABLE..=FORMAT_VERSION).contains(&m.version) {
            return Err(Error::ModelFormat(format!(
                "version {} (this build reads {OLDEST_READABLE} to {FORMAT_VERSION})",
                m.version
            )));
        }
        if let Model::Hybrid(h) = &m.model {
            h.check()?;
        }
        Ok(m)
    }
}

/// Deviation (mm) along unit normals that a machine with `map` adds to nominal surface
/// points: `d_k = e(p_k) · n_k` — what the gap diagnosis' part domain uses as the
/// machine's predicted deviation (positive where material is left, as the measurement
/// contract's deviations, when `n` is the outward normal and `e` moves the tool away).
/// `points` and `normals` must have the same length (shorter one bounds the output).
pub fn normal_deviation(
    map: &VolumetricMap,
    points: &[[f64; 3]],
    normals: &[[f64; 3]],
) -> Vec<f64> {
    let e = map.model.eval_many(points);
    e.iter()
        .zip(normals)
        .map(|(e, n)| e[0] * n[0] + e[1] * n[1] + e[2] * n[2])
        .collect()
}
