//! Compensated programs for CAM post-processors (issue 14): contour-error pre-compensation
//! by pre-distortion of the reference path (module `predistort`, function [`predistort()`]).
pub mod predistort;

pub use predistort::{
    Error, ErrorStats, PredistortOptions, PredistortPoint, Predistorted, predistort,
};
