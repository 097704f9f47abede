//! Serde types of the HTTP bodies that both the server (`api`) and the command line (`cli`)
//! use, so the two cannot drift: one module per resource.

pub mod contour;
pub mod iso230;
pub mod iso230_comp;
