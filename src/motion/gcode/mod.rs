//! G-code reader: an ISO 6983 / Fanuc-style subset with Sinumerik TRAORI/TRAFOOF.
//!
//! Files: `reader` (the reader: comments, words, modal state, blocks) and its tests.

mod reader;
#[cfg(test)]
mod tests;

pub use crate::motion::program::{Block, Feed, Motion, Plane, Pose, Program};
pub use reader::parse;
