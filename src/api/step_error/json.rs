//! Lean decoding of the bodies of the step-error routes.
//!
//! One serde_json pass with visitors that write the points straight into flat buffers: typed
//! decoding into `Vec<StepErrorSegment>` allocates a `Vec` per segment, and 100,000 segments are
//! about 70-130 MB of JSON, so the decoder is most of the route's time.

use std::borrow::Cow;
use std::fmt;

use serde::de::{self, DeserializeSeed, Deserializer, MapAccess, SeqAccess, Visitor};

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

/// A decoded `{"tool_radius"?: mm, "segments": [...]}` body.
#[derive(Debug, Default)]
pub struct SegmentsBody {
    /// Ball radius, mm, when sent.
    pub tool_radius: Option<f64>,
    /// The segments.
    pub batch: SegmentBatch,
}

impl<'de> de::Deserialize<'de> for SegmentsBody {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(BodyVisitor)
    }
}

struct BodyVisitor;

impl<'de> Visitor<'de> for BodyVisitor {
    type Value = SegmentsBody;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an object {\"tool_radius\": mm, \"segments\": [...]}")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<SegmentsBody, A::Error> {
        let mut out = SegmentsBody::default();
        out.batch.start.push(0);
        let mut have_segments = false;
        while let Some(key) = map.next_key::<Cow<'de, str>>()? {
            match key.as_ref() {
                "tool_radius" => out.tool_radius = Some(map.next_value()?),
                "segments" => {
                    map.next_value_seed(SegmentsSeed(&mut out.batch))?;
                    have_segments = true;
                }
                other => {
                    return Err(de::Error::custom(format!(
                        "unknown field '{other}': the body has tool_radius and segments"
                    )));
                }
            }
        }
        if !have_segments {
            return Err(de::Error::custom("segments is missing"));
        }
        Ok(out)
    }
}

struct SegmentsSeed<'b>(&'b mut SegmentBatch);

impl<'de> DeserializeSeed<'de> for SegmentsSeed<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for SegmentsSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(
            "segments: an array of {\"cl\": [[x,y,z],[x,y,z]], \"cc\": [[x,y,z], ...]} objects",
        )
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut index = 0;
        while seq
            .next_element_seed(SegmentSeed {
                batch: &mut *self.0,
                index,
            })?
            .is_some()
        {
            index += 1;
        }
        Ok(())
    }
}

struct SegmentSeed<'b> {
    batch: &'b mut SegmentBatch,
    index: usize,
}

impl<'de> DeserializeSeed<'de> for SegmentSeed<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for SegmentSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "segments[{}] to be an object with cl and cc", self.index)
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let i = self.index;
        let b = self.batch;
        let begin = b.cc.len();
        let (mut cl, mut have_cl, mut have_cc) = ([[0.0; 3]; 2], false, false);
        while let Some(key) = map.next_key::<Cow<'de, str>>()? {
            match key.as_ref() {
                "cl" => {
                    cl = map.next_value::<[[f64; 3]; 2]>().map_err(|_| {
                        de::Error::custom(format!(
                            "segments[{i}]: cl must be two points [[x,y,z],[x,y,z]] (mm)"
                        ))
                    })?;
                    have_cl = true;
                }
                "cc" if !have_cc => {
                    map.next_value_seed(PointsSeed(&mut b.cc)).map_err(|_| {
                        de::Error::custom(format!(
                            "segments[{i}]: cc must be an array of points [[x,y,z], ...] (mm)"
                        ))
                    })?;
                    have_cc = true;
                }
                other => {
                    return Err(de::Error::custom(format!(
                        "segments[{i}]: unknown or repeated field '{other}': a segment has only cl and cc"
                    )));
                }
            }
        }
        if !have_cl || !have_cc {
            b.cc.truncate(begin);
            let what = if have_cl {
                "cc is missing"
            } else {
                "cl is missing"
            };
            return Err(de::Error::custom(format!("segments[{i}]: {what}")));
        }
        b.cl.push(cl);
        b.start.push(b.cc.len());
        Ok(())
    }
}

struct PointsSeed<'b>(&'b mut Vec<[f64; 3]>);

impl<'de> DeserializeSeed<'de> for PointsSeed<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for PointsSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an array of points [x, y, z]")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(p) = seq.next_element::<[f64; 3]>()? {
            self.0.push(p);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(raw: &str) -> Result<SegmentsBody, String> {
        serde_json::from_str::<SegmentsBody>(raw).map_err(|e| e.to_string())
    }

    #[test]
    fn decodes_segments_in_any_key_order_and_reports_bad_ones() {
        let raw = r#" {"segments": [ {"cc": [[0,0,0],[1,0,0.5],[2,0,0]], "cl": [[0,0,5],[2,0,5]]},
                        {"cl":[[1e0,2,3],[4,5,6]],"cc":[[1,2,3],[2,3,4],[3,4,5],[4,5,6]]} ], "tool_radius": 5} "#;
        let b = decode(raw).unwrap();
        assert_eq!(b.tool_radius, Some(5.0));
        let b = b.batch;
        assert_eq!(b.len(), 2);
        assert_eq!(b.get(0).1.len(), 3);
        assert_eq!(b.get(1).0, [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(b.get(1).1[3], [4.0, 5.0, 6.0]);
        for (bad, msg) in [
            (
                r#"{"segments": [{"cl": [[0,0,5]], "cc": [[0,0,0]]}]}"#,
                "segments[0]: cl must be two points",
            ),
            (
                r#"{"segments": [{"cl": [[0,0,5],[1,1,1]]}]}"#,
                "cc is missing",
            ),
            (
                r#"{"segments": [{"cl": [[0,0,5],[1,1,1]], "cc": [[0,0]]}]}"#,
                "cc must be an array",
            ),
            (
                r#"{"segments": [{"cl": [[0,0,5],[1,1,1]], "cc": [], "x": 1}]}"#,
                "unknown or repeated field 'x'",
            ),
            (r#"{"segments": [1]}"#, "segments[0]"),
            (r#"{"tool_radius": 1}"#, "segments is missing"),
            (r#"{"segments": [], "y": 2}"#, "unknown field 'y'"),
        ] {
            let e = decode(bad);
            assert!(
                e.as_ref().is_err_and(|m| m.contains(msg)),
                "{e:?} should say {msg}"
            );
        }
    }
}
