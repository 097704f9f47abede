//! Normal-offset compensation (Chen et al. 2024): compensated points, the reconstructed compensated
//! surface at any density, and compensated ball-end cutter-location points.

pub mod error;
pub mod offsets;
pub mod surface;

pub use error::Error;
pub use offsets::compensate_points;
pub use surface::{CompensatedGrid, CompensatedSurface};
