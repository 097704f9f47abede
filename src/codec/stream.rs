//! Decoding a step-error body while it arrives.
//!
//! Moving 100 MB over a socket takes about as long as parsing it, so the two overlap: the
//! receiving task cuts the body into blocks that each start at an element of the segments
//! array ([`BlockCutter`]: at a '{' whose previous non-whitespace byte is ','), and worker
//! threads parse the blocks as they come ([`decode_blocks`]). A block is trusted only if the
//! one before it, parsed for real, ended exactly at its start (after a ','), and the first
//! block is parsed from the body's start, so by induction every trusted block starts at an
//! element. Any doubt (a bad cut, any error) decodes the whole body again with
//! [`super::json::decode`], which also words the error, so the result is always that of the
//! whole-body decoder.

use std::sync::Mutex;
use std::sync::mpsc::{Receiver, Sender};

use super::cursor::Cursor;
use super::error::DecodeError;
use super::json::{self, PartEnd};
use super::top::{Top, TopStep};
use crate::step_error::{SegmentBatch, SegmentsBody};

/// A piece of the body sent to [`decode_blocks`].
#[derive(Debug)]
pub enum Block {
    /// The next bytes of the body.
    Data(Vec<u8>),
    /// The body is complete (a closed channel without it means the body was cut off).
    End,
}

/// How far back from a block's end to look for an element start.
const CUT_SEARCH_BYTES: usize = 1 << 20;

/// Collects the arriving chunks into blocks of about `target` bytes cut at element starts.
pub struct BlockCutter {
    cur: Vec<u8>,
    target: usize,
    total: usize,
    tx: Sender<Block>,
}

impl BlockCutter {
    /// Blocks of at least `target` bytes (the last may be shorter) go to `tx`.
    pub fn new(target: usize, tx: Sender<Block>) -> Self {
        BlockCutter {
            cur: Vec::with_capacity(Self::capacity(target)),
            target,
            total: 0,
            tx,
        }
    }

    /// Room for a block and the chunk that overshoots it, so a block is never moved.
    fn capacity(target: usize) -> usize {
        target + target / 4 + (512 << 10)
    }

    /// Bytes received so far.
    pub fn total(&self) -> usize {
        self.total
    }

    /// Appends a chunk; sends a block when one is full and a cut is found in it.
    pub fn push(&mut self, chunk: &[u8]) {
        self.total += chunk.len();
        self.cur.extend_from_slice(chunk);
        if self.cur.len() < self.target {
            return;
        }
        if let Some(cut) = last_element_start(&self.cur) {
            let mut next = Vec::with_capacity(Self::capacity(self.target));
            next.extend_from_slice(&self.cur[cut..]);
            self.cur.truncate(cut);
            let block = std::mem::replace(&mut self.cur, next);
            // A closed receiver means the decoder gave up: the rest is not needed.
            let _ = self.tx.send(Block::Data(block));
        }
    }

    /// Sends the rest and the end mark.
    pub fn finish(self) {
        if !self.cur.is_empty() {
            let _ = self.tx.send(Block::Data(self.cur));
        }
        let _ = self.tx.send(Block::End);
    }
}

/// The last '{' (within [`CUT_SEARCH_BYTES`] of the end, not at 0) whose previous
/// non-whitespace byte is ','.
fn last_element_start(b: &[u8]) -> Option<usize> {
    let low = b.len().saturating_sub(CUT_SEARCH_BYTES).max(1);
    let mut i = b.len();
    while i > low {
        i -= 1;
        if b[i] == b'{'
            && b[..i]
                .iter()
                .rev()
                .find(|c| !matches!(**c, b' ' | b'\n' | b'\r' | b'\t'))
                .is_some_and(|&c| c == b',')
        {
            return Some(i);
        }
    }
    None
}

/// How a block's parse ended.
enum BlockEnd {
    /// After a ',' at the block's end: the next block continues the array.
    Cut,
    /// The array closed and the body ended in this block; the object's state after it.
    Done(Top),
    /// Anything else (an error, or a cut that did not hold).
    Doubt,
}

/// Parses block `index`: the first from the body's start, the others from an element.
fn parse_block(index: usize, b: &[u8]) -> (SegmentBatch, BlockEnd) {
    let mut c = Cursor { b, i: 0 };
    let mut top = Top {
        have_segments: true,
        ..Top::default()
    };
    let from = if index == 0 {
        top = Top::default();
        if top.open(&mut c) != Ok(TopStep::SegmentsOpen) {
            return (SegmentBatch::default(), BlockEnd::Doubt);
        }
        c.ws();
        if c.peek() == Some(b']') {
            c.i += 1;
            let end = match top.resume(&mut c) {
                Ok(TopStep::End) => BlockEnd::Done(top),
                _ => BlockEnd::Doubt,
            };
            return (SegmentBatch::default(), end);
        }
        c.i
    } else {
        0
    };
    let (batch, end) = json::part(b, from, Some(b.len()));
    let end = match end {
        Ok(PartEnd::Cut) => BlockEnd::Cut,
        Ok(PartEnd::Close(at)) => {
            c.i = at;
            match top.resume(&mut c) {
                Ok(TopStep::End) => BlockEnd::Done(top),
                _ => BlockEnd::Doubt,
            }
        }
        Err(_) => BlockEnd::Doubt,
    };
    (batch, end)
}

/// Decodes the blocks from `rx` on up to `threads` threads (0 = all cores) as they arrive.
/// `Ok(None)` when the channel closed without [`Block::End`] (the body did not arrive whole).
pub fn decode_blocks(
    rx: Receiver<Block>,
    threads: usize,
) -> Result<Option<SegmentsBody>, DecodeError> {
    let threads = json::thread_count(threads);
    // (receiver, next block index, finished: Some(true) complete, Some(false) cut off)
    let queue = Mutex::new((rx, 0usize, None::<bool>));
    let done = Mutex::new(Vec::<(usize, Vec<u8>, SegmentBatch, BlockEnd)>::new());
    let work = || {
        loop {
            let (index, block) = {
                let mut q = queue.lock().expect("block queue");
                if q.2.is_some() {
                    return;
                }
                match q.0.recv() {
                    Ok(Block::Data(b)) => {
                        q.1 += 1;
                        (q.1 - 1, b)
                    }
                    Ok(Block::End) => {
                        q.2 = Some(true);
                        return;
                    }
                    Err(_) => {
                        q.2 = Some(false);
                        return;
                    }
                }
            };
            let (batch, end) = parse_block(index, &block);
            done.lock()
                .expect("decoded blocks")
                .push((index, block, batch, end));
        }
    };
    std::thread::scope(|s| {
        for _ in 1..threads {
            s.spawn(work);
        }
        work();
    });
    let (_, _, complete) = queue.into_inner().expect("block queue");
    if complete != Some(true) {
        return Ok(None);
    }
    let mut done = done.into_inner().expect("decoded blocks");
    done.sort_by_key(|d| d.0);
    let n = done.len();
    let mut first = None;
    let mut last = None;
    let trusted = done.iter().enumerate().all(|(i, d)| match &d.3 {
        BlockEnd::Cut => i + 1 < n,
        BlockEnd::Done(top) => {
            last = Some(*top);
            i + 1 == n
        }
        BlockEnd::Doubt => false,
    });
    if trusted && n > 1 {
        // The radius before the segments is in the first block's state, after them in the
        // last one's; both would be a repeated field (the whole-body decoder words it).
        let mut c = Cursor {
            b: &done[0].1,
            i: 0,
        };
        let mut top = Top::default();
        if top.open(&mut c) == Ok(TopStep::SegmentsOpen) {
            first = Some(top);
        }
    }
    let radius = match (trusted, n, first, last) {
        (true, 1, _, Some(top)) => Some(top.tool_radius),
        (true, _, Some(a), Some(b)) if !(a.have_radius && b.have_radius) => {
            Some(if a.have_radius {
                a.tool_radius
            } else {
                b.tool_radius
            })
        }
        _ => None,
    };
    match radius {
        Some(tool_radius) => Ok(Some(SegmentsBody {
            tool_radius,
            parts: done.into_iter().map(|d| d.2).collect(),
        })),
        None => {
            let body: Vec<u8> = done.into_iter().flat_map(|d| d.1).collect();
            json::decode(&body, threads).map(Some)
        }
    }
}

#[cfg(test)]
mod tests;
