//! Decoding of the step-error bodies `{"tool_radius"?: mm, "segments": [{"cl": [[x,y,z],[x,y,z]],
//! "cc": [[x,y,z], ...]}, ...]}` straight from the bytes into flat buffers.
//!
//! 100,000 segments of 20 CC points are 70-130 MB of JSON, so decoding is most of the route's
//! time. This is a JSON parser for this one shape (any whitespace, keys in any order, the full
//! number grammar; anything else is rejected with a sentence naming the segment), with numbers
//! read by [`super::number`]. Large bodies are read by several threads: the segments array is
//! cut at guessed element starts, each part is parsed on its own, and a cut is used only if
//! the part before it, parsed for real, ends exactly there (otherwise that part simply reads on,
//! and the parts after are dropped), so the result is always the sequential parse.
//!
//! The seams: [`super::top`] reads the object around the segments array, this file the array
//! (split over threads), [`super::cursor`] one segment and the JSON tokens.

use super::cursor::{Cursor, is_ws, segment};
use super::error::DecodeError;
use super::top::{Top, TopStep};
use crate::step_error::{SegmentBatch, SegmentsBody};

/// Bodies smaller than this are parsed by one thread.
const PARALLEL_MIN_BYTES: usize = 1 << 20;
/// How far past a guessed cut to look for an element start.
const CUT_SEARCH_BYTES: usize = 1 << 16;

/// Decodes a whole body, using up to `threads` threads for the segments (0 = all cores).
pub fn decode(body: &[u8], threads: usize) -> Result<SegmentsBody, DecodeError> {
    decode_in(body, threads, PARALLEL_MIN_BYTES)
}

/// The number of threads `threads` asks for (0 = all cores).
pub(super) fn thread_count(threads: usize) -> usize {
    if threads == 0 {
        std::thread::available_parallelism().map_or(1, |t| t.get())
    } else {
        threads
    }
    .clamp(1, 16)
}

/// [`decode`] with bodies of at least `parallel_min` bytes split over the threads.
pub(super) fn decode_in(
    body: &[u8],
    threads: usize,
    parallel_min: usize,
) -> Result<SegmentsBody, DecodeError> {
    let threads = thread_count(threads);
    let mut c = Cursor { b: body, i: 0 };
    let mut top = Top::default();
    let mut parts = Vec::new();
    let mut step = top.open(&mut c)?;
    while step == TopStep::SegmentsOpen {
        let (p, end) = segments(body, c.i, threads, parallel_min)?;
        parts = p;
        c.i = end;
        step = top.resume(&mut c)?;
    }
    Ok(SegmentsBody {
        tool_radius: top.tool_radius,
        parts,
    })
}

/// How a part of the segments array ended.
pub(super) enum PartEnd {
    /// At the start of the next part, right after a ','.
    Cut,
    /// After the array's closing ']' (the position).
    Close(usize),
}

/// A segment the part could not read: its index within the part and the sentence after
/// `segments[i]`.
pub(super) struct SegmentFailure {
    pub local: usize,
    pub what: String,
}

/// Parses the segments array whose '[' ends at `open`; returns the parts and the position
/// after its ']'.
fn segments(
    b: &[u8],
    open: usize,
    threads: usize,
    parallel_min: usize,
) -> Result<(Vec<SegmentBatch>, usize), DecodeError> {
    let mut c = Cursor { b, i: open };
    c.ws();
    if c.peek() == Some(b']') {
        return Ok((vec![SegmentBatch::default()], c.i + 1));
    }
    let first = c.i;
    let mut cuts = vec![first];
    if threads > 1 && b.len() - first >= parallel_min {
        for t in 1..threads {
            let guess = first + (b.len() - first) * t / threads;
            if let Some(cut) = element_start_after(b, guess.max(cuts[cuts.len() - 1] + 1))
                && cut > cuts[cuts.len() - 1]
            {
                cuts.push(cut);
            }
        }
    }
    let ends: Vec<Option<usize>> = cuts[1..].iter().map(|&c| Some(c)).chain([None]).collect();
    let results: Vec<(SegmentBatch, Result<PartEnd, SegmentFailure>)> = if cuts.len() == 1 {
        vec![part(b, first, None)]
    } else {
        std::thread::scope(|s| {
            let handles: Vec<_> = cuts[1..]
                .iter()
                .zip(&ends[1..])
                .map(|(&from, &stop)| s.spawn(move || part(b, from, stop)))
                .collect();
            let mut all = vec![part(b, first, ends[0])];
            all.extend(
                handles
                    .into_iter()
                    .map(|h| h.join().expect("segment decoder panicked")),
            );
            all
        })
    };
    let mut parts = Vec::with_capacity(results.len());
    let mut before = 0;
    for (batch, end) in results {
        let n = batch.len();
        match end {
            Ok(PartEnd::Cut) => parts.push(batch),
            Ok(PartEnd::Close(end)) => {
                parts.push(batch);
                return Ok((parts, end));
            }
            Err(f) => {
                return Err(DecodeError(format!(
                    "segments[{}]{}",
                    before + f.local,
                    f.what
                )));
            }
        }
        before += n;
    }
    unreachable!("the last part has no cut to end at")
}

/// The first position at or after `from` (within [`CUT_SEARCH_BYTES`]) holding '{' whose
/// previous non-whitespace byte is ',': where an element of the segments array may start.
fn element_start_after(b: &[u8], from: usize) -> Option<usize> {
    let to = (from + CUT_SEARCH_BYTES).min(b.len());
    (from..to).find(|&i| {
        b[i] == b'{'
            && b[..i]
                .iter()
                .rev()
                .find(|c| !is_ws(**c))
                .is_some_and(|&c| c == b',')
    })
}

/// Parses segment objects from `from` until the array closes or, right after a ',', the
/// position `stop` is reached.
pub(super) fn part(
    b: &[u8],
    from: usize,
    stop: Option<usize>,
) -> (SegmentBatch, Result<PartEnd, SegmentFailure>) {
    let mut batch = SegmentBatch::default();
    let span = stop.unwrap_or(b.len()) - from;
    // Generous guesses from the text length: reserved pages never touched cost nothing.
    batch.cc.reserve(span / 32);
    batch.cl.reserve(span / 600);
    batch.start.reserve(span / 600);
    let mut c = Cursor { b, i: from };
    let end = loop {
        let local = batch.len();
        if let Err(what) = segment(&mut c, &mut batch) {
            break Err(SegmentFailure { local, what });
        }
        c.ws();
        match c.next() {
            Some(b',') => {
                c.ws();
                if Some(c.i) == stop {
                    break Ok(PartEnd::Cut);
                }
            }
            Some(b']') => break Ok(PartEnd::Close(c.i)),
            _ => {
                break Err(SegmentFailure {
                    local: local + 1,
                    what: format!(
                        ": invalid JSON at byte {}: expected ',' or ']' after the previous segment",
                        c.i - 1
                    ),
                });
            }
        }
    };
    (batch, end)
}

#[cfg(test)]
mod tests;
