//! Segment batches in flat storage and their exact step errors on all cores.
//!
//! A request of 100,000 segments would be 100,000 small `Vec`s as [`StepErrorSegment`]s; the
//! decoder (`codec::segments`) writes them instead into three flat buffers per decoding
//! thread ([`SegmentBatch`]), and [`solve_batch`] reads them in place.
//!
//! [`StepErrorSegment`]: crate::geometry::StepErrorSegment

use crate::geometry::{self, StepError};

/// Segments decoded into flat storage: segment `i` has CL points `cl[i]` and CC points
/// `cc[start[i]..start[i + 1]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentBatch {
    /// The two ball centres of each segment, mm.
    pub cl: Vec<[[f64; 3]; 2]>,
    /// All CC points, mm.
    pub cc: Vec<[f64; 3]>,
    /// Offsets into `cc`, `len() + 1` entries.
    pub start: Vec<usize>,
}

impl Default for SegmentBatch {
    fn default() -> Self {
        SegmentBatch {
            cl: Vec::new(),
            cc: Vec::new(),
            start: vec![0],
        }
    }
}

impl SegmentBatch {
    /// Number of segments.
    pub fn len(&self) -> usize {
        self.cl.len()
    }

    /// True without segments.
    pub fn is_empty(&self) -> bool {
        self.cl.is_empty()
    }

    /// CL points and CC curve of segment `i`.
    pub fn get(&self, i: usize) -> ([[f64; 3]; 2], &[[f64; 3]]) {
        (self.cl[i], &self.cc[self.start[i]..self.start[i + 1]])
    }

    /// All segments in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = ([[f64; 3]; 2], &[[f64; 3]])> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }

    /// The parts one after the other in one batch.
    pub fn concat(parts: Vec<SegmentBatch>) -> SegmentBatch {
        let mut parts = parts.into_iter();
        let Some(mut out) = parts.next() else {
            return SegmentBatch::default();
        };
        for p in parts {
            let base = out.cc.len();
            out.cl.extend_from_slice(&p.cl);
            out.cc.extend_from_slice(&p.cc);
            out.start.extend(p.start[1..].iter().map(|s| s + base));
        }
        out
    }
}

/// A decoded body: the segments in consecutive parts (one per decoding thread).
#[derive(Debug, Clone, Default)]
pub struct SegmentsBody {
    /// Ball radius, mm, when sent (`null` counts as not sent).
    pub tool_radius: Option<f64>,
    /// The segments, in order, split into parts.
    pub parts: Vec<SegmentBatch>,
}

impl SegmentsBody {
    /// Number of segments.
    pub fn len(&self) -> usize {
        self.parts.iter().map(SegmentBatch::len).sum()
    }

    /// True without segments.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// All segments in order: CL points and CC curve.
    pub fn iter(&self) -> impl Iterator<Item = ([[f64; 3]; 2], &[[f64; 3]])> + '_ {
        self.parts.iter().flat_map(SegmentBatch::iter)
    }
}

/// Most threads [`solve_batch`] starts: beyond eight the flat batch is memory-bound.
const MAX_THREADS: usize = 8;
/// Fewest segments a thread of [`solve_batch`] takes (fewer do not pay for the spawn).
const MIN_PER_THREAD: usize = 2048;

/// Exact step errors of the segments of `parts` (in order), split over the machine's cores
/// (at most eight) by [`geometry::step_errors_split`], each thread solving four
/// segments side by side. Units: mm. Errors name the first bad segment's index in the whole
/// batch ([`geometry::Error::InSegment`]).
pub fn solve_batch(
    tool_radius_mm: f64,
    parts: &[SegmentBatch],
) -> Result<Vec<StepError>, geometry::Error> {
    let n: usize = parts.iter().map(SegmentBatch::len).sum();
    let threads = std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(MAX_THREADS);
    // Segments `from..to` of the whole batch, across the parts.
    let range = |from: usize, to: usize| {
        let mut skip = from;
        parts
            .iter()
            .flat_map(move |p| {
                let start = skip.min(p.len());
                skip -= start;
                (start..p.len()).map(move |i| p.get(i))
            })
            .take(to - from)
    };
    geometry::step_errors_split(tool_radius_mm, n, threads, MIN_PER_THREAD, range)
}
