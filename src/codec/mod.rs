//! Hand-written fast decoders for large request bodies: the step-error segment batches
//! (`{"tool_radius"?: mm, "segments": [{"cl": ..., "cc": ...}, ...]}`) read straight into
//! flat buffers ([`crate::step_error::SegmentBatch`]), whole ([`decode`]) or while the body
//! arrives ([`decode_blocks`]). Not HTTP: `api` reads the body and maps [`DecodeError`] to 400.
//!
//! Why hand-written: 100,000 segments are 70-130 MB of JSON and serde_json's typed decoding
//! (a `Vec` per segment) is most of the route's time; see BENCHMARKS.md (step error).

mod cursor;
mod error;
mod json;
mod number;
mod stream;
mod top;

pub use error::DecodeError;
pub use json::decode;
pub use stream::{Block, BlockCutter, decode_blocks};
