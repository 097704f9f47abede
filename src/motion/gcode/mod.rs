//! G-code reader: an ISO 6983 / Fanuc-style reader (lenient, strict on request) with
//! Sinumerik TRAORI/TRAFOOF.
//!
//! Files: `lexer` (comments, words), `reader` (modal state, what a line asks for), `moves`
//! (blocks, dwell, cycles in force, M codes), `frame` (work offsets, tool lengths,
//! G28/G30/G53), `cycles` (canned drilling cycles expanded), `options` (options and
//! warnings) and the tests.

mod cycles;
mod frame;
mod lexer;
mod moves;
mod options;
mod reader;
#[cfg(test)]
mod tests;

pub use crate::motion::program::{Block, Feed, Motion, Plane, Pose, Program};
pub use options::{ReadOptions, Warning};
pub use reader::{parse, parse_with};
