//! The segment decoder against serde_json: property tests (fixed seeds) over random segment
//! batches that serde_json writes with varied number spellings, key orders and whitespace;
//! the thread split against the sequential parse; the error sentences.

use std::io;

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use serde::Serialize;
use serde_json::ser::Formatter;
use serde_json::{Value, json};

use super::*;

type Segment = ([[f64; 3]; 2], Vec<[f64; 3]>);

/// A serde_json formatter that varies what JSON allows and the decoder must read: the
/// spelling of each number (shortest, `e`, `E+`, Debug, 17 and 25 significant digits),
/// whitespace around every structural character, and `\u0063` for the `c` of `"cc"` keys.
struct Varied<'a> {
    styles: &'a [u8],
    spaces: &'a [u8],
    escape_cc: bool,
    n: usize,
    w: usize,
}

impl Varied<'_> {
    fn ws<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        let k = self.spaces[self.w % self.spaces.len()];
        self.w += 1;
        w.write_all(match k % 7 {
            0..=2 => b"",
            3 => b" ",
            4 => b"\n",
            5 => b"\t ",
            _ => b"\r\n  ",
        })
    }

    fn comma<W: ?Sized + io::Write>(&mut self, w: &mut W, first: bool) -> io::Result<()> {
        if !first {
            self.ws(w)?;
            w.write_all(b",")?;
        }
        self.ws(w)
    }
}

impl Formatter for Varied<'_> {
    fn write_f64<W: ?Sized + io::Write>(&mut self, w: &mut W, v: f64) -> io::Result<()> {
        let style = self.styles[self.n % self.styles.len()];
        self.n += 1;
        let text = match style % 6 {
            0 => ryu::Buffer::new().format_finite(v).to_string(),
            1 => format!("{v:e}"),
            2 => format!("{v:E}").replace('E', "E+").replace("E+-", "E-"),
            3 => format!("{v:?}"),
            4 => format!("{v:.16e}"),
            _ => format!("{v:.24e}"),
        };
        w.write_all(text.as_bytes())
    }
    fn begin_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.ws(w)?;
        w.write_all(b"[")
    }
    fn end_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.ws(w)?;
        w.write_all(b"]")
    }
    fn begin_array_value<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> io::Result<()> {
        self.comma(w, first)
    }
    fn begin_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.ws(w)?;
        w.write_all(b"{")
    }
    fn end_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.ws(w)?;
        w.write_all(b"}")
    }
    fn begin_object_key<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> io::Result<()> {
        self.comma(w, first)
    }
    fn begin_object_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.ws(w)?;
        w.write_all(b":")?;
        self.ws(w)
    }
    fn write_string_fragment<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        s: &str,
    ) -> io::Result<()> {
        if self.escape_cc && s == "cc" {
            w.write_all(br"\u0063c")
        } else {
            w.write_all(s.as_bytes())
        }
    }
}

#[derive(Serialize)]
struct ClFirst<'a> {
    cl: &'a [[f64; 3]; 2],
    cc: &'a [[f64; 3]],
}

#[derive(Serialize)]
struct CcFirst<'a> {
    cc: &'a [[f64; 3]],
    cl: &'a [[f64; 3]; 2],
}

#[derive(Serialize)]
#[serde(untagged)]
enum Seg<'a> {
    Cl(ClFirst<'a>),
    Cc(CcFirst<'a>),
}

#[derive(Serialize)]
struct RadiusFirst<'a> {
    tool_radius: Option<f64>,
    segments: Vec<Seg<'a>>,
}

#[derive(Serialize)]
struct SegmentsFirst<'a> {
    segments: Vec<Seg<'a>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    tool_radius: Option<f64>,
}

/// How serde_json writes a body: key orders, number spellings, whitespace, escapes.
#[derive(Debug, Clone)]
struct Spelling {
    cl_first: Vec<bool>,
    radius_first: bool,
    styles: Vec<u8>,
    spaces: Vec<u8>,
    escape_cc: bool,
}

/// The body `{"tool_radius": r, "segments": [...]}` as serde_json writes it with `how`.
fn write_body(r: Option<f64>, segs: &[Segment], how: &Spelling) -> Vec<u8> {
    let segments: Vec<Seg> = segs
        .iter()
        .enumerate()
        .map(|(i, (cl, cc))| {
            if how.cl_first[i % how.cl_first.len()] {
                Seg::Cl(ClFirst { cl, cc })
            } else {
                Seg::Cc(CcFirst { cc, cl })
            }
        })
        .collect();
    let mut out = Vec::new();
    let f = Varied {
        styles: &how.styles,
        spaces: &how.spaces,
        escape_cc: how.escape_cc,
        n: 0,
        w: 0,
    };
    let mut ser = serde_json::Serializer::with_formatter(&mut out, f);
    if how.radius_first {
        RadiusFirst {
            tool_radius: r,
            segments,
        }
        .serialize(&mut ser)
    } else {
        SegmentsFirst {
            segments,
            tool_radius: r,
        }
        .serialize(&mut ser)
    }
    .unwrap();
    out
}

/// Coordinates at one of several magnitudes (mm, µm, m, sub-nm, huge), both signs.
fn segment() -> impl Strategy<Value = Segment> {
    prop::sample::select(vec![1.0, 1e-4, 1e3, 1e-12, 7e15]).prop_flat_map(|scale| {
        let point = prop::array::uniform3((-0.5f64..0.5).prop_map(move |u| u * scale));
        (
            prop::array::uniform2(point.clone()),
            prop::collection::vec(point, 3..33),
        )
    })
}

fn spelling() -> impl Strategy<Value = Spelling> {
    (
        prop::collection::vec(any::<bool>(), 1..8),
        any::<bool>(),
        prop::collection::vec(any::<u8>(), 1..16),
        prop::collection::vec(any::<u8>(), 1..16),
        any::<bool>(),
    )
        .prop_map(
            |(cl_first, radius_first, styles, spaces, escape_cc)| Spelling {
                cl_first,
                radius_first,
                styles,
                spaces,
                escape_cc,
            },
        )
}

fn config(cases: u32, seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn flat(body: &SegmentsBody) -> SegmentBatch {
    SegmentBatch::concat(body.parts.clone())
}

/// Deterministic segments (no generator needed) for the hand-made error cases.
fn fixed_segments(n: usize) -> Vec<Segment> {
    (0..n)
        .map(|i| {
            let x = i as f64 * 0.37;
            let p = |k: f64| [x + k, (x * k).sin() * 3.0, 5.0 + (x + k).cos() * 1e-3];
            (
                [p(0.0), p(1.0)],
                (0..3 + i % 20).map(|k| p(k as f64 * 0.1)).collect(),
            )
        })
        .collect()
}

proptest! {
    #![proptest_config(config(96, 0x853C_49E6_748F_EA9B))]
    /// Whatever serde_json writes decodes to exactly the values it was given, and to what
    /// serde_json itself reads back (within its own rounding).
    #[test]
    fn decodes_what_serde_json_writes(
        segs in prop::collection::vec(segment(), 1..40),
        r in prop::option::of(0.5f64..10.5),
        how in spelling(),
    ) {
        let text = write_body(r, &segs, &how);
        let shown = String::from_utf8_lossy(&text);
        let got = decode(&text, 1).map_err(|e| TestCaseError::fail(format!("{e}\n{shown}")))?;
        prop_assert_eq!(got.tool_radius, r);
        let b = flat(&got);
        prop_assert_eq!(b.len(), segs.len());
        let v: Value = serde_json::from_slice(&text).unwrap();
        let sv = v["segments"].as_array().unwrap();
        for (i, (cl, cc)) in segs.iter().enumerate() {
            let (gcl, gcc) = b.get(i);
            prop_assert_eq!(&gcl, cl, "segment {}", i);
            prop_assert_eq!(gcc, &cc[..], "segment {}", i);
            let scc = sv[i]["cc"].as_array().unwrap();
            prop_assert_eq!(scc.len(), gcc.len());
            for (p, q) in scc.iter().zip(gcc) {
                for k in 0..3 {
                    let s = p[k].as_f64().unwrap();
                    prop_assert!((s - q[k]).abs() <= q[k].abs() * 4.0 * f64::EPSILON);
                }
            }
        }
    }
}

#[test]
fn decodes_serde_jsons_own_compact_and_pretty_output() {
    let segs = fixed_segments(50);
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

proptest! {
    #![proptest_config(config(24, 0xDA94_2042_E4DD_58B5))]
    /// Split over threads at guessed element starts, the result is the sequential parse.
    #[test]
    fn splitting_over_threads_gives_the_sequential_result(
        segs in prop::collection::vec(segment(), 200..600),
        how in spelling(),
    ) {
        let text = write_body(Some(3.0), &segs, &how);
        let one = decode_in(&text, 1, 0).unwrap();
        prop_assert_eq!(one.parts.len(), 1);
        for threads in [2, 3, 7] {
            let many = decode_in(&text, threads, 0).unwrap();
            prop_assert_eq!(many.parts.len(), threads, "the cuts should all hold");
            prop_assert_eq!(flat(&many), flat(&one));
            prop_assert_eq!(many.tool_radius, Some(3.0));
        }
    }
}

#[test]
fn an_error_in_a_late_part_names_its_segment_in_the_whole_array() {
    let segs = fixed_segments(600);
    let doc = json!({"tool_radius": 3.0, "segments": segs.iter().map(|(cl, cc)| json!({"cl": cl, "cc": cc})).collect::<Vec<_>>()});
    let text = serde_json::to_string(&doc).unwrap();
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
    let body = |segments: &str| format!(r#"{{"tool_radius": 5, "segments": [{seg}, {segments}]}}"#);
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

/// A small body serde_json writes pretty, for the truncation and mutation checks.
fn small_body() -> Vec<u8> {
    let segs = fixed_segments(4);
    let doc = json!({"tool_radius": 2.0, "segments": segs.iter().map(|(cl, cc)| json!({"cl": cl, "cc": cc})).collect::<Vec<_>>()});
    serde_json::to_string_pretty(&doc).unwrap().into_bytes()
}

#[test]
fn never_accepts_a_truncation_serde_json_rejects() {
    let text = small_body();
    for n in 0..text.len() {
        let cut = &text[..n];
        if serde_json::from_slice::<Value>(cut).is_err() {
            assert!(decode(cut, 1).is_err(), "{}", String::from_utf8_lossy(cut));
        }
    }
}

proptest! {
    #![proptest_config(config(20_000, 0x1234_5678_9ABC_DEF1))]
    /// One to three bytes changed to JSON-ish bytes: never accepted when serde_json refuses,
    /// never a panic, and the thread split agrees.
    #[test]
    fn never_accepts_what_serde_json_rejects_and_never_panics(
        changes in prop::collection::vec((any::<prop::sample::Index>(), any::<prop::sample::Index>()), 1..=3),
    ) {
        let alphabet = b"{}[],:\"0123456789-+.eE \nabcnul\\";
        let mut t = small_body();
        for (at, byte) in &changes {
            let i = at.index(t.len());
            t[i] = alphabet[byte.index(alphabet.len())];
        }
        let ours = decode(&t, 1);
        if serde_json::from_slice::<Value>(&t).is_err() {
            prop_assert!(ours.is_err(), "{}", String::from_utf8_lossy(&t));
        }
        prop_assert_eq!(ours.is_ok(), decode_in(&t, 3, 0).is_ok());
    }
}
