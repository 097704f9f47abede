//! The segment decoder against serde_json and its error sentences.

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
