//! Lean decoding of the `segments` array of the step-error routes.
//!
//! serde_json first checks the whole body's syntax and hands over `segments` as raw text; this
//! module then reads the numbers straight into flat buffers, split across threads at segment
//! boundaries. It exists for speed: typed serde decoding of 100,000 segments (about 130 MB of
//! JSON per million segments) allocates a `Vec` per segment and dominates the route's time.

/// Segments decoded into flat storage: segment `i` has CL points `cl[i]` and CC points
/// `cc[start[i]..start[i + 1]]`.
#[derive(Debug, Default, Clone)]
pub struct SegmentBatch {
    /// The two ball centres of each segment, mm.
    pub cl: Vec<[[f64; 3]; 2]>,
    /// All CC points, mm.
    pub cc: Vec<[f64; 3]>,
    /// Offsets into `cc`, `len() + 1` entries.
    pub start: Vec<usize>,
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
}

/// Byte ranges of the elements of a JSON array given as syntactically valid text.
pub fn element_ranges(raw: &[u8]) -> Result<Vec<(usize, usize)>, String> {
    let mut i = 0;
    while i < raw.len() && raw[i].is_ascii_whitespace() {
        i += 1;
    }
    if raw.get(i) != Some(&b'[') {
        return Err("segments must be an array of {\"cl\": [[x,y,z],[x,y,z]], \"cc\": [[x,y,z], ...]} objects".into());
    }
    let mut out = Vec::new();
    let mut depth = 0usize;
    let mut start = None;
    let mut in_str = false;
    let mut esc = false;
    for (k, &c) in raw.iter().enumerate().skip(i) {
        if in_str {
            if esc {
                esc = false;
            } else if c == b'\\' {
                esc = true;
            } else if c == b'"' {
                in_str = false;
            }
            continue;
        }
        match c {
            b'"' => in_str = true,
            b'[' | b'{' => {
                depth += 1;
                if depth == 2 && start.is_none() {
                    start = Some(k);
                }
            }
            b']' | b'}' => {
                if depth == 2
                    && let Some(s) = start.take()
                {
                    out.push((s, k + 1));
                }
                depth = depth.saturating_sub(1);
            }
            b',' if depth == 1 => {}
            c if depth == 1 && !c.is_ascii_whitespace() => {
                return Err(format!(
                    "segments[{}] must be an object with cl and cc",
                    out.len()
                ));
            }
            _ => {}
        }
    }
    Ok(out)
}

struct Cursor<'a> {
    b: &'a [u8],
    i: usize,
}

impl Cursor<'_> {
    fn ws(&mut self) {
        while self.i < self.b.len() && self.b[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.ws();
        self.b.get(self.i).copied()
    }

    fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn number(&mut self) -> Option<f64> {
        self.ws();
        let s = self.i;
        while self.i < self.b.len()
            && matches!(
                self.b[self.i],
                b'0'..=b'9' | b'-' | b'+' | b'.' | b'e' | b'E'
            )
        {
            self.i += 1;
        }
        std::str::from_utf8(&self.b[s..self.i]).ok()?.parse().ok()
    }

    fn point(&mut self) -> Option<[f64; 3]> {
        if !self.eat(b'[') {
            return None;
        }
        let x = self.number()?;
        if !self.eat(b',') {
            return None;
        }
        let y = self.number()?;
        if !self.eat(b',') {
            return None;
        }
        let z = self.number()?;
        self.eat(b']').then_some([x, y, z])
    }

    fn key(&mut self) -> Option<&[u8]> {
        if !self.eat(b'"') {
            return None;
        }
        let s = self.i;
        while self.i < self.b.len() && self.b[self.i] != b'"' {
            self.i += 1;
        }
        let k = &self.b[s..self.i];
        self.i += 1;
        Some(k)
    }
}

/// Decodes the segment objects at `ranges` of `raw` (indices from `first`) into `out`.
pub fn decode_into(
    raw: &[u8],
    ranges: &[(usize, usize)],
    first: usize,
    out: &mut SegmentBatch,
) -> Result<(), String> {
    out.start.push(out.cc.len());
    for (k, &(s, e)) in ranges.iter().enumerate() {
        let idx = first + k;
        let bad = |what: &str| format!("segments[{idx}]: {what}");
        let mut c = Cursor {
            b: &raw[s..e],
            i: 0,
        };
        if !c.eat(b'{') {
            return Err(bad("must be an object with cl and cc"));
        }
        let (mut cl, mut have_cl, mut have_cc) = ([[0.0; 3]; 2], false, false);
        let cc_begin = out.cc.len();
        if !c.eat(b'}') {
            loop {
                let key = c
                    .key()
                    .ok_or_else(|| bad("expected a field name"))?
                    .to_vec();
                if !c.eat(b':') {
                    return Err(bad("expected ':'"));
                }
                match key.as_slice() {
                    b"cl" => {
                        let pts = (|| {
                            if !c.eat(b'[') {
                                return None;
                            }
                            let a = c.point()?;
                            if !c.eat(b',') {
                                return None;
                            }
                            let b = c.point()?;
                            c.eat(b']').then_some([a, b])
                        })();
                        cl =
                            pts.ok_or_else(|| bad("cl must be two points [[x,y,z],[x,y,z]] (mm)"))?;
                        have_cl = true;
                    }
                    b"cc" => {
                        if have_cc {
                            return Err(bad("cc given twice"));
                        }
                        let ok = (|| {
                            if !c.eat(b'[') {
                                return None;
                            }
                            if c.eat(b']') {
                                return Some(());
                            }
                            loop {
                                out.cc.push(c.point()?);
                                if c.eat(b']') {
                                    return Some(());
                                }
                                if !c.eat(b',') {
                                    return None;
                                }
                            }
                        })();
                        ok.ok_or_else(|| bad("cc must be an array of points [[x,y,z], ...] (mm)"))?;
                        have_cc = true;
                    }
                    other => {
                        return Err(bad(&format!(
                            "unknown field '{}': a segment has only cl and cc",
                            String::from_utf8_lossy(other)
                        )));
                    }
                }
                if c.eat(b'}') {
                    break;
                }
                if !c.eat(b',') {
                    return Err(bad("expected ',' or '}'"));
                }
            }
        }
        if !have_cl || !have_cc {
            out.cc.truncate(cc_begin);
            return Err(bad(if have_cl {
                "cc is missing"
            } else {
                "cl is missing"
            }));
        }
        out.cl.push(cl);
        out.start.push(out.cc.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decodes_segments_in_any_key_order_and_reports_bad_ones() {
        let raw = br#" [ {"cc": [[0,0,0],[1,0,0.5],[2,0,0]], "cl": [[0,0,5],[2,0,5]]},
                        {"cl":[[1e0,2,3],[4,5,6]],"cc":[[1,2,3],[2,3,4],[3,4,5],[4,5,6]]} ] "#;
        let r = element_ranges(raw).unwrap();
        assert_eq!(r.len(), 2);
        let mut b = SegmentBatch::default();
        decode_into(raw, &r, 0, &mut b).unwrap();
        assert_eq!(b.len(), 2);
        assert_eq!(b.get(0).1.len(), 3);
        assert_eq!(b.get(1).0, [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(b.get(1).1[3], [4.0, 5.0, 6.0]);
        for (bad, msg) in [
            (
                &br#"[{"cl": [[0,0,5]], "cc": [[0,0,0]]}]"#[..],
                "cl must be two points",
            ),
            (br#"[{"cl": [[0,0,5],[1,1,1]]}]"#, "cc is missing"),
            (
                br#"[{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0]], "x": 1}]"#,
                "cc must be an array",
            ),
            (
                br#"[{"cl": [[0,0,5],[1,1,1]], "cc": [], "x": 1}]"#,
                "unknown field 'x'",
            ),
            (br#"[1]"#, "must be an object"),
        ] {
            let e = element_ranges(bad).and_then(|r| {
                let mut b = SegmentBatch::default();
                decode_into(bad, &r, 0, &mut b)
            });
            assert!(
                e.as_ref().is_err_and(|m| m.contains(msg)),
                "{e:?} should say {msg}"
            );
        }
    }
}
