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

use super::number::{BadNumber, parse_number};

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

/// Why a body was rejected: a sentence for the client (the API answers it as 400).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodeError(pub String);

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

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

/// Where the object around the segments has got to.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Top {
    pub tool_radius: Option<f64>,
    pub have_radius: bool,
    pub have_segments: bool,
}

/// Where [`Top`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TopStep {
    /// Just after the '[' of the segments array.
    SegmentsOpen,
    /// After the closing '}' and trailing whitespace, at the end of the body.
    End,
}

impl Top {
    /// From the body's start: '{' and the fields up to the segments array or the end.
    pub(super) fn open(&mut self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        c.ws();
        c.expect(
            b'{',
            "the body to be an object {\"tool_radius\": mm, \"segments\": [...]}",
        )
        .map_err(syntax)?;
        c.ws();
        if c.peek() == Some(b'}') {
            c.i += 1;
            return self.finish(c);
        }
        self.fields(c)
    }

    /// After the segments array's ']': the remaining fields up to the end.
    pub(super) fn resume(&mut self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        match self.after_value(c)? {
            true => self.fields(c),
            false => self.finish(c),
        }
    }

    /// From a field name on.
    fn fields(&mut self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        loop {
            let at = c.i;
            let key = c.key().map_err(syntax)?;
            c.ws();
            match key.as_ref() {
                "tool_radius" if !self.have_radius => {
                    self.have_radius = true;
                    self.tool_radius = if c.literal(b"null") {
                        None
                    } else {
                        Some(parse_number(c.b, &mut c.i).map_err(|_| {
                            DecodeError(
                                "tool_radius must be a number: the ball radius in mm".into(),
                            )
                        })?)
                    };
                }
                "segments" if !self.have_segments => {
                    self.have_segments = true;
                    c.expect(
                        b'[',
                        "segments to be an array of {\"cl\": [[x,y,z],[x,y,z]], \"cc\": [[x,y,z], ...]} objects",
                    )
                    .map_err(syntax)?;
                    return Ok(TopStep::SegmentsOpen);
                }
                "tool_radius" | "segments" => {
                    return Err(DecodeError(format!(
                        "{key} appears twice in the body (at byte {at}): send it once"
                    )));
                }
                other => {
                    return Err(DecodeError(format!(
                        "unknown field '{other}': the body has tool_radius and segments"
                    )));
                }
            }
            if !self.after_value(c)? {
                return self.finish(c);
            }
        }
    }

    /// After a field's value: true at ',' (and whitespace), false at the closing '}'.
    fn after_value(&self, c: &mut Cursor) -> Result<bool, DecodeError> {
        c.ws();
        match c.next() {
            Some(b',') => {
                c.ws();
                Ok(true)
            }
            Some(b'}') => Ok(false),
            _ => Err(syntax((c.i - 1, "',' or '}' after a field of the body"))),
        }
    }

    /// After the closing '}': only whitespace may follow; the segments must have come.
    fn finish(&self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        c.ws();
        if c.i < c.b.len() {
            return Err(syntax((c.i, "the end of the body after the closing '}'")));
        }
        if !self.have_segments {
            return Err(DecodeError(
                "segments is missing: send {\"tool_radius\": mm, \"segments\": [{\"cl\": [[x,y,z],[x,y,z]], \"cc\": [[x,y,z], ...]}]}".into(),
            ));
        }
        Ok(TopStep::End)
    }
}

/// Where a syntax error is and what was expected there.
type Syntax = (usize, &'static str);

fn syntax((at, what): Syntax) -> DecodeError {
    DecodeError(format!("invalid JSON body at byte {at}: expected {what}"))
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

const CL_SHAPE: &str = "cl must be two points [[x,y,z],[x,y,z]] (mm)";
const CC_SHAPE: &str = "cc must be an array of points [[x,y,z], ...] (mm)";

/// Parses one segment object into `batch`; on error, the text after `segments[i]` (the batch
/// is then left part-filled: the whole decode fails).
fn segment(c: &mut Cursor, batch: &mut SegmentBatch) -> Result<(), String> {
    if c.peek() != Some(b'{') {
        return Err(format!(
            " must be an object {{\"cl\": [[x,y,z],[x,y,z]], \"cc\": [[x,y,z], ...]}} (invalid JSON at byte {})",
            c.i
        ));
    }
    c.i += 1;
    c.ws();
    let mut cl = None;
    let mut have_cc = false;
    if c.peek() == Some(b'}') {
        c.i += 1;
    } else {
        loop {
            let key = c.key().map_err(|e| format!(": {}", syntax(e)))?;
            c.ws();
            match key.as_ref() {
                "cl" if cl.is_none() => {
                    cl = Some(c.two_points().map_err(|e| shape_error(CL_SHAPE, "cl", e))?);
                }
                "cc" if !have_cc => {
                    c.points(&mut batch.cc)
                        .map_err(|e| shape_error(CC_SHAPE, "cc", e))?;
                    have_cc = true;
                }
                other => {
                    return Err(format!(
                        ": unknown or repeated field '{other}': a segment has only cl and cc"
                    ));
                }
            }
            c.ws();
            match c.next() {
                Some(b',') => c.ws(),
                Some(b'}') => break,
                _ => {
                    return Err(format!(
                        ": invalid JSON at byte {}: expected ',' or '}}' after a field of the segment",
                        c.i - 1
                    ));
                }
            }
        }
    }
    match (cl, have_cc) {
        (Some(cl), true) => {
            batch.cl.push(cl);
            batch.start.push(batch.cc.len());
            Ok(())
        }
        (None, _) => Err(": cl is missing".into()),
        (Some(_), false) => Err(": cc is missing".into()),
    }
}

/// What went wrong inside a `cl` or `cc` value.
enum PointsError {
    /// The shape (brackets, commas, count) or a malformed number, at a byte.
    Shape(usize),
    /// A number that overflows: the point's index, the coordinate's index.
    NonFinite(usize, usize),
}

fn shape_error(shape: &str, name: &str, e: PointsError) -> String {
    match e {
        PointsError::Shape(at) => format!(": {shape} (invalid at byte {at})"),
        PointsError::NonFinite(p, k) => format!(
            ": {name}[{p}][{k}] is not a finite number (it overflows to infinity): send coordinates in mm"
        ),
    }
}

fn is_ws(c: u8) -> bool {
    matches!(c, b' ' | b'\n' | b'\r' | b'\t')
}

pub(super) struct Cursor<'a> {
    pub b: &'a [u8],
    pub i: usize,
}

impl<'a> Cursor<'a> {
    #[inline(always)]
    pub(super) fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }

    #[inline(always)]
    fn next(&mut self) -> Option<u8> {
        let c = self.peek();
        self.i += 1;
        c
    }

    #[inline(always)]
    pub(super) fn ws(&mut self) {
        while let Some(&c) = self.b.get(self.i) {
            if !is_ws(c) {
                break;
            }
            self.i += 1;
        }
    }

    #[inline(always)]
    fn expect(&mut self, want: u8, what: &'static str) -> Result<(), Syntax> {
        if self.peek() == Some(want) {
            self.i += 1;
            Ok(())
        } else {
            Err((self.i, what))
        }
    }

    fn literal(&mut self, word: &[u8]) -> bool {
        if self.b.get(self.i..).is_some_and(|r| r.starts_with(word)) {
            self.i += word.len();
            true
        } else {
            false
        }
    }

    /// An object key and the ':' after it (whitespace allowed before the ':').
    fn key(&mut self) -> Result<std::borrow::Cow<'a, str>, Syntax> {
        const WHAT: &str = "a field name in double quotes";
        let start = self.i;
        self.expect(b'"', WHAT)?;
        let from = self.i;
        let mut escaped = false;
        loop {
            match self.next() {
                Some(b'"') => break,
                Some(b'\\') => {
                    escaped = true;
                    self.i += 1;
                }
                Some(c) if c >= 0x20 => {}
                _ => return Err((self.i - 1, "a closing '\"' of the field name")),
            }
        }
        let raw = &self.b[from..self.i - 1];
        let key = if escaped {
            // Rare: let serde_json apply the escapes.
            let s: String =
                serde_json::from_slice(&self.b[start..self.i]).map_err(|_| (start, WHAT))?;
            std::borrow::Cow::Owned(s)
        } else {
            String::from_utf8_lossy(raw)
        };
        self.ws();
        self.expect(b':', "':' after the field name")?;
        Ok(key)
    }

    #[inline(always)]
    fn number(&mut self, p: usize, k: usize) -> Result<f64, PointsError> {
        let at = self.i;
        parse_number(self.b, &mut self.i).map_err(|e| match e {
            BadNumber::NonFinite => PointsError::NonFinite(p, k),
            BadNumber::NotANumber | BadNumber::Malformed => PointsError::Shape(at),
        })
    }

    #[inline(always)]
    fn byte(&mut self, want: u8) -> Result<(), PointsError> {
        self.ws();
        if self.peek() == Some(want) {
            self.i += 1;
            self.ws();
            Ok(())
        } else {
            Err(PointsError::Shape(self.i))
        }
    }

    /// `[x, y, z]`, the `p`-th point of its array.
    #[inline(always)]
    fn point(&mut self, p: usize) -> Result<[f64; 3], PointsError> {
        self.byte(b'[')?;
        let x = self.number(p, 0)?;
        self.byte(b',')?;
        let y = self.number(p, 1)?;
        self.byte(b',')?;
        let z = self.number(p, 2)?;
        self.ws();
        if self.peek() == Some(b']') {
            self.i += 1;
            Ok([x, y, z])
        } else {
            Err(PointsError::Shape(self.i))
        }
    }

    /// `[[x,y,z], [x,y,z]]`.
    fn two_points(&mut self) -> Result<[[f64; 3]; 2], PointsError> {
        self.byte(b'[')?;
        let a = self.point(0)?;
        self.byte(b',')?;
        let b = self.point(1)?;
        self.ws();
        if self.peek() == Some(b']') {
            self.i += 1;
            Ok([a, b])
        } else {
            Err(PointsError::Shape(self.i))
        }
    }

    /// `[[x,y,z], ...]` appended to `out`.
    fn points(&mut self, out: &mut Vec<[f64; 3]>) -> Result<(), PointsError> {
        self.byte(b'[')?;
        if self.peek() == Some(b']') {
            self.i += 1;
            return Ok(());
        }
        let mut p = 0;
        loop {
            out.push(self.point(p)?);
            p += 1;
            self.ws();
            match self.next() {
                Some(b',') => self.ws(),
                Some(b']') => return Ok(()),
                _ => return Err(PointsError::Shape(self.i - 1)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::{Value, json};

    /// xorshift64: fixed seeds, no dependency.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    type Segment = ([[f64; 3]; 2], Vec<[f64; 3]>);

    fn random_segments(rng: &mut Rng, n: usize) -> Vec<Segment> {
        (0..n)
            .map(|_| {
                let scale = [1.0, 1e-4, 1e3, 1e-12, 7e15][rng.below(5)];
                let p = |rng: &mut Rng| {
                    let mut q = [0.0; 3];
                    for v in &mut q {
                        *v = (rng.unit() - 0.5) * scale;
                    }
                    q
                };
                let cl = [p(rng), p(rng)];
                let m = 3 + (rng.next() % 30) as usize;
                let cc = (0..m).map(|_| p(rng)).collect();
                (cl, cc)
            })
            .collect()
    }

    /// One number in one of several JSON spellings that all read back to exactly `v`.
    fn write_number(rng: &mut Rng, v: f64, out: &mut String) {
        let t = match rng.below(5) {
            0 | 1 => ryu::Buffer::new().format(v).to_string(),
            2 => format!("{v:e}"),
            3 => format!("{v:E}").replace('E', "E+").replace("E+-", "E-"),
            _ => format!("{v:?}"),
        };
        out.push_str(&t);
    }

    fn ws(rng: &mut Rng, out: &mut String, on: bool) {
        if on {
            for _ in 0..rng.below(3) {
                out.push([' ', '\n', '\t', '\r'][rng.below(4)]);
            }
        }
    }

    fn write_point(rng: &mut Rng, p: &[f64; 3], out: &mut String, spaced: bool) {
        out.push('[');
        for (k, v) in p.iter().enumerate() {
            if k > 0 {
                ws(rng, out, spaced);
                out.push(',');
            }
            ws(rng, out, spaced);
            write_number(rng, *v, out);
        }
        ws(rng, out, spaced);
        out.push(']');
    }

    fn write_body(rng: &mut Rng, r: Option<f64>, segs: &[Segment], spaced: bool) -> String {
        let mut out = String::new();
        let points = |rng: &mut Rng, ps: &[[f64; 3]], out: &mut String| {
            out.push('[');
            for (j, p) in ps.iter().enumerate() {
                if j > 0 {
                    ws(rng, out, spaced);
                    out.push(',');
                }
                ws(rng, out, spaced);
                write_point(rng, p, out, spaced);
            }
            ws(rng, out, spaced);
            out.push(']');
        };
        let mut segments = String::from("[");
        for (i, (cl, cc)) in segs.iter().enumerate() {
            if i > 0 {
                segments.push(',');
            }
            ws(rng, &mut segments, spaced);
            segments.push('{');
            let cl_first = rng.below(2) == 0;
            for field in 0..2 {
                if field > 0 {
                    segments.push(',');
                }
                ws(rng, &mut segments, spaced);
                if (field == 0) == cl_first {
                    segments.push_str("\"cl\"");
                    ws(rng, &mut segments, spaced);
                    segments.push(':');
                    ws(rng, &mut segments, spaced);
                    points(rng, &cl[..], &mut segments);
                } else {
                    segments.push_str(if rng.below(4) == 0 {
                        "\"\\u0063c\""
                    } else {
                        "\"cc\""
                    });
                    ws(rng, &mut segments, spaced);
                    segments.push(':');
                    ws(rng, &mut segments, spaced);
                    points(rng, cc, &mut segments);
                }
                ws(rng, &mut segments, spaced);
            }
            segments.push('}');
        }
        ws(rng, &mut segments, spaced);
        segments.push(']');
        let radius = match r {
            Some(r) => ryu::Buffer::new().format(r).to_string(),
            None => "null".into(),
        };
        ws(rng, &mut out, spaced);
        out.push('{');
        ws(rng, &mut out, spaced);
        if rng.below(2) == 0 {
            out.push_str(&format!("\"tool_radius\":{radius},\"segments\":"));
            ws(rng, &mut out, spaced);
            out.push_str(&segments);
        } else {
            out.push_str("\"segments\"");
            ws(rng, &mut out, spaced);
            out.push(':');
            out.push_str(&segments);
            out.push_str(&format!(",\"tool_radius\" : {radius}"));
        }
        ws(rng, &mut out, spaced);
        out.push('}');
        ws(rng, &mut out, spaced);
        out
    }

    fn flat(body: &SegmentsBody) -> SegmentBatch {
        SegmentBatch::concat(body.parts.clone())
    }

    #[test]
    fn reads_back_random_bodies_exactly_and_as_serde_json_does() {
        let mut rng = Rng(0x853C_49E6_748F_EA9B);
        for round in 0..60 {
            let n = 1 + rng.below(40);
            let segs = random_segments(&mut rng, n);
            let r = (round % 5 != 0).then(|| 0.5 + rng.unit() * 10.0);
            let text = write_body(&mut rng, r, &segs, round % 2 == 0);
            let got = decode(text.as_bytes(), 1).unwrap_or_else(|e| panic!("{e}\n{text}"));
            assert_eq!(got.tool_radius, r);
            let b = flat(&got);
            assert_eq!(b.len(), segs.len());
            // The same body through serde_json: same shape, values within its rounding.
            let v: Value = serde_json::from_str(&text).unwrap();
            let sv = v["segments"].as_array().unwrap();
            for (i, (cl, cc)) in segs.iter().enumerate() {
                let (gcl, gcc) = b.get(i);
                assert_eq!(&gcl, cl, "round {round} segment {i}");
                assert_eq!(gcc, &cc[..], "round {round} segment {i}");
                let scc = sv[i]["cc"].as_array().unwrap();
                assert_eq!(scc.len(), gcc.len());
                for (p, q) in scc.iter().zip(gcc) {
                    for k in 0..3 {
                        let s = p[k].as_f64().unwrap();
                        assert!((s - q[k]).abs() <= q[k].abs() * 4.0 * f64::EPSILON);
                    }
                }
            }
        }
        // serde_json's own compact and pretty output
        let segs = random_segments(&mut rng, 50);
        let doc = json!({"tool_radius": 5.0, "segments": segs.iter().map(|(cl, cc)| json!({"cl": cl, "cc": cc})).collect::<Vec<_>>()});
        for text in [
            serde_json::to_string(&doc).unwrap(),
            serde_json::to_string_pretty(&doc).unwrap(),
        ] {
            let b = flat(&decode(text.as_bytes(), 1).unwrap());
            for (i, (cl, cc)) in segs.iter().enumerate() {
                assert_eq!(b.get(i), (*cl, &cc[..]));
            }
        }
    }

    #[test]
    fn splitting_over_threads_gives_the_sequential_result() {
        let mut rng = Rng(0xDA94_2042_E4DD_58B5);
        let segs = random_segments(&mut rng, 600);
        for spaced in [false, true] {
            let text = write_body(&mut rng, Some(3.0), &segs, spaced);
            let one = decode_in(text.as_bytes(), 1, 0).unwrap();
            assert_eq!(one.parts.len(), 1);
            for threads in [2, 3, 7] {
                let many = decode_in(text.as_bytes(), threads, 0).unwrap();
                assert_eq!(many.parts.len(), threads, "the cuts should all hold");
                assert_eq!(flat(&many), flat(&one));
                assert_eq!(many.tool_radius, Some(3.0));
            }
        }
        // An error in a late part names its segment by its index in the whole array.
        let text = write_body(&mut rng, Some(3.0), &segs, false);
        let at = text.len() * 9 / 10;
        let open = text[..at].rfind("\"cc\"").unwrap();
        let broken = format!("{}\"cx\"{}", &text[..open], &text[open + 4..]);
        let want = decode_in(broken.as_bytes(), 1, 0).unwrap_err();
        assert!(want.0.contains("unknown or repeated field 'cx'"), "{want}");
        let index: usize = want.0["segments[".len()..want.0.find(']').unwrap()]
            .parse()
            .unwrap();
        assert!(index > 500, "{want}");
        for threads in [2, 3, 7] {
            assert_eq!(decode_in(broken.as_bytes(), threads, 0).unwrap_err(), want);
        }
        // A cut guessed inside a string (',{' in a field name) is not taken for a segment start.
        let fake: String = format!(
            "{{\"segments\":[{}]}}",
            (0..400)
                .map(|i| if i == 100 {
                    format!(
                        "{{\"cl\":[[0,0,5],[1,0,5]],\"cc\":[[0,0,0],[1,0,0],[2,0,0]],\"{}\":1}}",
                        ",{".repeat(3000)
                    )
                } else {
                    "{\"cl\":[[0,0,5],[1,0,5]],\"cc\":[[0,0,0],[1,0,0],[2,0,0]]}".into()
                })
                .collect::<Vec<_>>()
                .join(",")
        );
        let want = decode_in(fake.as_bytes(), 1, 0).unwrap_err();
        assert!(
            want.0
                .starts_with("segments[100]: unknown or repeated field"),
            "{want}"
        );
        for threads in [2, 3, 4] {
            assert_eq!(decode_in(fake.as_bytes(), threads, 0).unwrap_err(), want);
        }
    }

    #[test]
    fn rejects_what_is_not_the_shape_with_a_sentence() {
        let seg = r#"{"cl": [[0,0,5],[1,0,5]], "cc": [[0,0,0],[0.5,0,0.1],[1,0,0]]}"#;
        let body =
            |segments: &str| format!(r#"{{"tool_radius": 5, "segments": [{seg}, {segments}]}}"#);
        for (bad, msg) in [
            (
                body(r#"{"cl": [[0,0,5]], "cc": [[0,0,0]]}"#),
                "segments[1]: cl must be two points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1],[2,2,2]], "cc": [[0,0,0]]}"#),
                "segments[1]: cl must be two points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]]}"#),
                "segments[1]: cc is missing",
            ),
            (
                body(r#"{"cc": [[0,0,5],[1,1,1]]}"#),
                "segments[1]: cl is missing",
            ),
            (body(r#"{}"#), "segments[1]: cl is missing"),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0]]}"#),
                "segments[1]: cc must be an array of points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0,0,0]]}"#),
                "segments[1]: cc must be an array of points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0,"1"]]}"#),
                "segments[1]: cc must be an array of points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0,NaN]]}"#),
                "segments[1]: cc must be an array of points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0,01]]}"#),
                "segments[1]: cc must be an array of points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0,1],]}"#),
                "segments[1]: cc must be an array of points",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0,0],[0,1,-1e999]]}"#),
                "segments[1]: cc[1][2] is not a finite number",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1e400,1,1]], "cc": []}"#),
                "segments[1]: cl[1][0] is not a finite number",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [], "x": 1}"#),
                "segments[1]: unknown or repeated field 'x'",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]], "cc": [], "cc": []}"#),
                "segments[1]: unknown or repeated field 'cc'",
            ),
            (
                body(r#"{"cl": [[0,0,5],[1,1,1]] "cc": []}"#),
                "segments[1]: invalid JSON at byte",
            ),
            (body("1"), "segments[1] must be an object"),
            (body(""), "segments[1] must be an object"),
            (
                format!(r#"{{"segments": [{seg} {seg}]}}"#),
                "segments[1]: invalid JSON at byte",
            ),
            (r#"{"tool_radius": 1}"#.into(), "segments is missing"),
            (r#"{}"#.into(), "segments is missing"),
            (r#"{"segments": [], "y": 2}"#.into(), "unknown field 'y'"),
            (
                r#"{"segments": {}}"#.into(),
                "expected segments to be an array",
            ),
            (
                r#"{"tool_radius": "5", "segments": []}"#.into(),
                "tool_radius must be a number",
            ),
            (
                r#"{"tool_radius": 5, "tool_radius": 5, "segments": []}"#.into(),
                "tool_radius appears twice",
            ),
            (
                r#"{"segments": [], "segments": []}"#.into(),
                "segments appears twice",
            ),
            (
                r#"{"segments": []} x"#.into(),
                "invalid JSON body at byte 17: expected the end of the body",
            ),
            (
                r#"[]"#.into(),
                "invalid JSON body at byte 0: expected the body to be an object",
            ),
            (
                r#"{"segments": [],}"#.into(),
                "invalid JSON body at byte 16: expected a field name",
            ),
            (
                r#"{segments: []}"#.into(),
                "invalid JSON body at byte 1: expected a field name",
            ),
            (String::new(), "invalid JSON body at byte 0"),
        ] {
            let e = decode(bad.as_bytes(), 1).unwrap_err();
            assert!(e.0.contains(msg), "{bad}\n  gave: {e}\n  want: {msg}");
        }
        let ok = decode(br#" {"segments" : [ ] , "tool_radius" : null } "#, 1).unwrap();
        assert!(ok.is_empty() && ok.tool_radius.is_none());
    }

    #[test]
    fn never_accepts_what_serde_json_rejects_and_never_panics() {
        let mut rng = Rng(0x1234_5678_9ABC_DEF1);
        let segs = random_segments(&mut rng, 4);
        let text = write_body(&mut rng, Some(2.0), &segs, true).into_bytes();
        // every truncation
        for n in 0..text.len() {
            let cut = &text[..n];
            if serde_json::from_slice::<Value>(cut).is_err() {
                assert!(decode(cut, 1).is_err(), "{}", String::from_utf8_lossy(cut));
            }
        }
        // random byte changes
        let alphabet = b"{}[],:\"0123456789-+.eE \nabcnul\\";
        for _ in 0..20_000 {
            let mut t = text.clone();
            for _ in 0..1 + rng.below(3) {
                let at = rng.below(t.len());
                t[at] = alphabet[rng.below(alphabet.len())];
            }
            let ours = decode(&t, 1);
            if serde_json::from_slice::<Value>(&t).is_err() {
                assert!(ours.is_err(), "{}", String::from_utf8_lossy(&t));
            }
            assert_eq!(ours.is_ok(), decode_in(&t, 3, 0).is_ok());
        }
    }
}
