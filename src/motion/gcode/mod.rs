//! G-code reader: an ISO 6983 / Fanuc-style reader (lenient, strict on request) with
//! Sinumerik TRAORI/TRAFOOF.
//!
//! Files: `lexer` (comments, words), `reader` (modal state, what a line asks for), `codes`
//! (each G code, and the words that move nothing), `moves` (blocks, dwell, cycles in force,
//! M codes), `frame` (work offsets, tool lengths, G28/G30/G53), `modes` (path control: G61,
//! G61.1, G9, G64 P, G05.1, G08), `cycles` (canned drilling cycles expanded), `cutter`,
//! `cutter_corners` and `cutter_reader` (G41/G42 cutter radius compensation with caller-given
//! tool diameters), `options` (options and warnings), `trace` (per-line frames and word
//! positions for program rewriters) and the tests.

mod codes;
mod cutter;
mod cutter_corners;
mod cutter_reader;
mod cycles;
mod frame;
mod lexer;
mod modes;
mod moves;
mod options;
mod reader;
#[cfg(test)]
mod tests;
mod trace;

pub use crate::motion::program::{Block, Feed, Motion, Plane, Pose, Program};
pub use options::{ReadOptions, Warning};
pub use reader::{parse, parse_modes, parse_traced, parse_with};
pub use trace::{LineFrame, WordSpan, word_spans};
