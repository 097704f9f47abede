//! Volumetric error maps of a machine's working volume (seeds 001, 004; ISO 230-1).
mod additive;
mod components;
mod data;
mod error;
mod export;
mod fit;
mod hybrid;
mod kinematic;
mod lsq;
mod model;
mod network;
mod pspline;
mod synthetic;
mod trilinear;

pub use additive::{AxisLine, AxisLines, additive_grid};
pub use components::{AxisCurves, ComponentCurves, Curve, Squareness, component_curves};
pub use data::{Bounds, GridIndex, VolumetricData};
pub use error::Error;
pub use export::{MAX_TABLE_ROWS, TableSpec, compensation_table_csv};
pub use fit::{FitOptions, ModelScore, Prediction, VolumetricMap, fit, folds, normal_deviation};
pub use hybrid::{HybridModel, ResidualKind};
pub use kinematic::{FUNCTION_NAMES, KinematicModel, SQUARENESS_NAMES, first_degree};
pub use model::{Model, ModelKind};
pub use network::{NetworkMap, NetworkOptions};
pub use pspline::{SmoothingSpline3, default_pieces};
pub use synthetic::{ShapeFamily, SyntheticMachine};
pub use trilinear::TrilinearMap;
