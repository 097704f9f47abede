//! Sim-to-real gap diagnosis: where simulation and measurement part, which unmodelled effect
//! causes it, and how far the gap shrinks once that effect is added (motion and part domains).
pub mod adopted;
pub mod align;
pub mod answer;
pub mod bounds;
pub mod effects;
pub mod error;
pub mod events;
pub mod fit;
pub mod judge;
pub mod motion;
pub mod part;
pub mod part_selfcheck;
pub mod patterns;
pub mod plant;
pub mod programs;
pub mod request;
pub mod selfcheck;
pub mod selfcheck_cases;
pub mod selfcheck_report;
pub mod selfcheck_where;
pub mod steps;
pub mod truth;
pub mod truth_clock;
pub mod truth_outside;
pub mod truth_wide;
pub mod unexplained;
pub mod usual;

pub use answer::{motion_answer, part_answer};
pub use effects::{Effect, Fitted};
pub use error::Error;
pub use events::Span;
pub use motion::{
    GapStats, MotionBlock, MotionDiagnosis, MotionOptions, diagnose_motion,
    diagnose_motion_structured,
};
pub use part::{PartBlock, PartDiagnosis, PartEffect, PartGrid, diagnose_part};
pub use request::{
    GapRequest, MAX_SAMPLES, MotionInputs, ProgramCommand, diagnose_motion_program,
    diagnose_motion_request, motion_inputs, motion_inputs_with, rows_to_columns,
};
