//! The JSON tokens of a segment body (whitespace, literals, strings as keys, numbers through
//! [`super::number`]) and one segment object `{"cl": [[x,y,z],[x,y,z]], "cc": [[x,y,z], ...]}`.

use super::error::DecodeError;
use super::number::{BadNumber, parse_number};
use crate::step_error::SegmentBatch;

/// Where a syntax error is and what was expected there.
pub(super) type Syntax = (usize, &'static str);

pub(super) fn syntax((at, what): Syntax) -> DecodeError {
    DecodeError(format!("invalid JSON body at byte {at}: expected {what}"))
}

const CL_SHAPE: &str = "cl must be two points [[x,y,z],[x,y,z]] (mm)";
const CC_SHAPE: &str = "cc must be an array of points [[x,y,z], ...] (mm)";

/// Parses one segment object into `batch`; on error, the text after `segments[i]` (the batch
/// is then left part-filled: the whole decode fails).
pub(super) fn segment(c: &mut Cursor, batch: &mut SegmentBatch) -> Result<(), String> {
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
pub(super) enum PointsError {
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

pub(super) fn is_ws(c: u8) -> bool {
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
    pub(super) fn next(&mut self) -> Option<u8> {
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
    pub(super) fn expect(&mut self, want: u8, what: &'static str) -> Result<(), Syntax> {
        if self.peek() == Some(want) {
            self.i += 1;
            Ok(())
        } else {
            Err((self.i, what))
        }
    }

    pub(super) fn literal(&mut self, word: &[u8]) -> bool {
        if self.b.get(self.i..).is_some_and(|r| r.starts_with(word)) {
            self.i += word.len();
            true
        } else {
            false
        }
    }

    /// An object key and the ':' after it (whitespace allowed before the ':').
    pub(super) fn key(&mut self) -> Result<std::borrow::Cow<'a, str>, Syntax> {
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
    pub(super) fn number(&mut self, p: usize, k: usize) -> Result<f64, PointsError> {
        let at = self.i;
        parse_number(self.b, &mut self.i).map_err(|e| match e {
            BadNumber::NonFinite => PointsError::NonFinite(p, k),
            BadNumber::NotANumber | BadNumber::Malformed => PointsError::Shape(at),
        })
    }

    #[inline(always)]
    pub(super) fn byte(&mut self, want: u8) -> Result<(), PointsError> {
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
    pub(super) fn point(&mut self, p: usize) -> Result<[f64; 3], PointsError> {
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
    pub(super) fn two_points(&mut self) -> Result<[[f64; 3]; 2], PointsError> {
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
    pub(super) fn points(&mut self, out: &mut Vec<[f64; 3]>) -> Result<(), PointsError> {
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
