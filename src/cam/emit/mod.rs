//! Re-emission keeping the post's structure: `emitter` (how each source line is written, by
//! its [`LinePlan`]) and `text` (numbers and the rewrite of a line's words).

mod emitter;
mod text;

pub use emitter::{Emitter, LineInfo, LinePlan, PathPiece};
pub use text::{decimals, format_number, rewrite, rounding_mm};
