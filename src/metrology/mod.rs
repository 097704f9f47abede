//! Machine-tool metrology by the standards: ISO 230-2:2014 positioning accuracy and
//! repeatability of an axis (from a table of measured positions or from a logged positioning
//! run) and ISO 230-4:2005 circular tests (circular deviation, radial deviation, circular
//! hysteresis about the orthogonal least-squares circle); and the axis's pitch-error
//! compensation table from an ISO 230-2 run, in the files controllers load.
//!
//! Pure: takes numbers, returns numbers or [`Error`]; no HTTP, SQL, tokio or files.

pub mod circle;
pub mod comp_format;
pub mod comp_model;
pub mod comp_reference;
pub mod comp_table;
pub mod error;
pub mod iso230_2;
pub mod iso230_4;
pub mod trace;

pub use circle::{Circle, fit_circle, fit_circle_kasa};
pub use comp_format::{LINUXCNC_MAX_TRIPLETS, csv_file, linuxcnc_file};
pub use comp_model::{Cyclic, CyclicTerm, PitchModel, fit_model};
pub use comp_table::{
    CompTable, MAX_CORRECTION_MM, Reference, SIGN_CONVENTION, TableSource, build_table,
};
pub use error::Error;
pub use iso230_2::{Axis230_2, PositionTable, Target230_2, evaluate_table};
pub use iso230_4::{Circular230_4, Hysteresis, circular_hysteresis, evaluate_circle};
pub use trace::{
    PositioningTrace, Settling, TraceEvaluation, TraceOptions, TraceReading, Visit, evaluate_trace,
    find_visits,
};
