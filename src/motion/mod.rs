//! Motion core (Zhang & Chen 2025): G-code reader, RTCP interpolation with a jerk-limited feed
//! profile, machine kinematics, the servo cascade per axis ([`servo`]: the cascade of openapi.yaml
//! schema `Servo`, Zhang & Chen 2025 §3), physical drive parameters, and contour error.
pub mod axes;
pub mod bounds;
pub mod contour;
pub mod controller;
pub mod def;
pub mod effects;
pub mod error;
pub mod gcode;
pub mod interpolate;
pub mod kinematics;
pub mod machine;
pub mod path_control;
pub mod physical;
pub mod predict;
pub mod profile;
pub mod program;
pub mod rk4;
pub mod servo;
pub mod settle;

pub use axes::{ServoAxes, check_period, machine_for_simulation, servo_axes, stored_definition};
pub use contour::{ContourReport, contour_error};
pub use controller::{ControllerDef, ControllerKind, ControllerLimits};
pub use def::{AxesDef, AxisDef, KinematicsKind, MachineDef};
pub use effects::{AddedEffects, AxisModel, Effects};
pub use error::Error;
pub use gcode::{Program, ReadOptions, Warning, parse, parse_modes, parse_with};
pub use interpolate::{Corner, DEFAULT_PERIOD_S, Trajectory, interpolate, interpolate_with};
pub use kinematics::{Kinematics, TableGeometry, ToolPose};
pub use machine::{AxisLimits, Machine, MachineAxis};
pub use path_control::{BlockEnd, PathControl};
pub use physical::{PhysicalAxis, StructuralMode};
pub use predict::{
    ContourPrediction, predict_contour_error, predict_program, predict_program_with,
    simulate_linear, simulate_machine,
};
pub use servo::{DiscreteServo, ServoAxis, simulate_axis};
pub use settle::{
    MAX_SETTLE_S, SETTLE_TOLERANCE_DEG, SETTLE_TOLERANCE_MM, Settle, predict_program_settled,
};
