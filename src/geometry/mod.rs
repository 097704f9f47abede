//! Surface and tool-path geometry: cubic splines through points, analytic height surfaces,
//! iso-parametric path sampling, exact step error of ball-end finishing (Zhang et al. 2023 eq. 1)
//! and the step-error network's input features.

mod error;
mod height_surface;
mod paths;
mod spline;
mod step_error;
mod step_features;

pub use error::Error;
pub use height_surface::{HeightJet, HeightSurface, HeightTerm};
pub use paths::{
    MAX_SEGMENTS, PathPlan, function_segments, grid_segments, height_surface_segments,
};
pub use spline::{CubicSpline3, Parameterization};
pub use step_error::{
    SegmentRef, StepError, StepErrorSegment, StepErrorSolver, check_segment, step_error,
    step_errors, step_errors_split,
};
pub use step_features::{FeatureFrame, PROFILE_FLOOR_UM, RowInfo, StepFeatures, StepInputs};
