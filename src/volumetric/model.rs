//! The model kinds behind one map, with a common evaluation interface.

use super::Error;
use super::data::Bounds;
use super::hybrid::HybridModel;
use super::kinematic::KinematicModel;
use super::network::NetworkMap;
use super::trilinear::TrilinearMap;
use serde::{Deserialize, Serialize};

/// Which model to fit; `Auto` picks the best by cross-validation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ModelKind {
    /// Fit every concrete kind and keep the best cross-validated one.
    #[default]
    Auto,
    /// Trilinear interpolation on the measured grid (the controller-table baseline).
    Trilinear,
    /// A 3-8-3 sigmoid network on z-scored coordinates.
    Network,
    /// The rigid-body ISO 230-1 model with 21 error parameters.
    Kinematic,
    /// Kinematic model plus a fitted residual (spline or network).
    Hybrid,
}

impl ModelKind {
    /// Every concrete kind, in the order they are tried and reported.
    pub const CONCRETE: [ModelKind; 4] = [
        ModelKind::Trilinear,
        ModelKind::Network,
        ModelKind::Kinematic,
        ModelKind::Hybrid,
    ];

    /// Parses `auto`, `trilinear`, `network`, `kinematic` or `hybrid`.
    pub fn parse(name: &str) -> Result<ModelKind, Error> {
        Ok(match name {
            "auto" => ModelKind::Auto,
            "trilinear" => ModelKind::Trilinear,
            "network" => ModelKind::Network,
            "kinematic" => ModelKind::Kinematic,
            "hybrid" => ModelKind::Hybrid,
            other => return Err(Error::UnknownModel(other.to_string())),
        })
    }

    /// The wire name.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Auto => "auto",
            ModelKind::Trilinear => "trilinear",
            ModelKind::Network => "network",
            ModelKind::Kinematic => "kinematic",
            ModelKind::Hybrid => "hybrid",
        }
    }
}

/// A fitted model of one kind. Variants differ in size (a table vs a few dozen
/// coefficients) but a map holds exactly one, so boxing buys nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Model {
    /// A trilinear table on the measured grid.
    Trilinear(TrilinearMap),
    /// A 3-8-3 network.
    Network(NetworkMap),
    /// A rigid-body ISO 230-1 model.
    Kinematic(KinematicModel),
    /// A kinematic model plus a residual.
    Hybrid(HybridModel),
}

impl Model {
    /// Its kind.
    pub fn kind(&self) -> ModelKind {
        match self {
            Model::Trilinear(_) => ModelKind::Trilinear,
            Model::Network(_) => ModelKind::Network,
            Model::Kinematic(_) => ModelKind::Kinematic,
            Model::Hybrid(_) => ModelKind::Hybrid,
        }
    }

    /// Predicted errors (mm) at `points` (mm); every model clamps coordinates outside
    /// its box into it.
    pub fn eval_many(&self, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        match self {
            Model::Trilinear(m) => points.iter().map(|&p| m.eval(p)).collect(),
            Model::Network(m) => m.eval_many(points),
            Model::Kinematic(m) => points.iter().map(|&p| m.eval(p)).collect(),
            Model::Hybrid(m) => m.eval_many(points),
        }
    }

    /// Numbers the model stores (what a controller or a file must hold).
    pub fn parameter_count(&self) -> usize {
        match self {
            Model::Trilinear(m) => m.parameter_count(),
            Model::Network(m) => m.parameter_count(),
            Model::Kinematic(m) => m.parameter_count(),
            Model::Hybrid(m) => m.parameter_count(),
        }
    }

    /// The box the model was fitted on (mm).
    pub fn bounds(&self) -> Bounds {
        match self {
            Model::Trilinear(m) => m.bounds(),
            Model::Network(m) => m.bounds(),
            Model::Kinematic(m) => m.bounds(),
            Model::Hybrid(m) => m.bounds(),
        }
    }
}
