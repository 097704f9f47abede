//! Streamed decoding gives the whole-body result, whatever the chunking.

use super::*;

fn streamed(
    body: &[u8],
    chunk: usize,
    target: usize,
    threads: usize,
) -> Option<Result<SegmentsBody, DecodeError>> {
    let (tx, rx) = std::sync::mpsc::channel();
    let mut cutter = BlockCutter::new(target, tx);
    for c in body.chunks(chunk.max(1)) {
        cutter.push(c);
    }
    assert_eq!(cutter.total(), body.len());
    cutter.finish();
    decode_blocks(rx, threads).transpose()
}

fn same(a: &Result<SegmentsBody, DecodeError>, b: &Result<SegmentsBody, DecodeError>) -> bool {
    match (a, b) {
        (Ok(a), Ok(b)) => {
            a.tool_radius.map(f64::to_bits) == b.tool_radius.map(f64::to_bits)
                && SegmentBatch::concat(a.parts.clone()) == SegmentBatch::concat(b.parts.clone())
        }
        (Err(a), Err(b)) => a == b,
        _ => false,
    }
}

fn body(n: usize, radius_first: bool) -> String {
    let segs: Vec<String> = (0..n)
        .map(|i| {
            let x = i as f64 * 0.1;
            format!(
                "{{\"cl\": [[{x},0,5],[{},0,5]], \"cc\": [[{x},0,0],[{},0.5,1e-3],[{},0,0]]}}",
                x + 0.1,
                x + 0.05,
                x + 0.1
            )
        })
        .collect();
    let segs = segs.join(",\n ");
    if radius_first {
        format!("{{\"tool_radius\": 5, \"segments\": [{segs}]}}")
    } else {
        format!("{{ \"segments\" : [ {segs} ] , \"tool_radius\":5.0 }} ")
    }
}

#[test]
fn gives_what_the_whole_body_decoder_gives() {
    let mut cases: Vec<String> = vec![
        body(0, true),
        body(1, false),
        body(500, true),
        body(500, false),
        body(500, false).replace(
            "\"tool_radius\":5.0",
            "\"tool_radius\":5.0,\"tool_radius\":2",
        ),
        format!("{{\"tool_radius\": 5, {}", &body(500, false)[1..]),
        body(500, true).replace("\"cc\"", "\"cx\""),
        body(500, true).replace("1e-3]", "1e999]"),
        body(500, true)[..9000].to_string(),
        body(500, true) + "x",
        body(500, true).replace(
            "},\n {\"cl\"",
            "}, {\"cl\":[[0,0,0],[1,1,1]],\"cc\":[], \"k,{\": 1}, {\"cl\"",
        ),
        String::new(),
        "{}".into(),
        "{\"segments\": []}".into(),
    ];
    let big = body(500, true);
    for at in [100, 5000, 12000, big.len() - 3] {
        let mut b = big.clone().into_bytes();
        b[at] = b'!';
        cases.push(String::from_utf8(b).unwrap());
    }
    for text in &cases {
        let want = json::decode(text.as_bytes(), 1);
        for (chunk, target, threads) in [
            (7, 64, 1),
            (100, 1000, 2),
            (333, 4096, 3),
            (1 << 20, 1 << 20, 2),
        ] {
            let got = streamed(text.as_bytes(), chunk, target, threads).expect("complete");
            assert!(
                same(&got, &want),
                "chunk {chunk} target {target}: {:?} vs {:?}\n{}",
                got.as_ref().map(|g| g.len()),
                want.as_ref().map(|w| w.len()),
                &text[..text.len().min(200)]
            );
            if let Ok(g) = got
                && text.len() > 20_000
                && target < 5000
            {
                assert!(g.parts.len() > 3, "the blocks should be decoded apart");
            }
        }
    }
}

#[test]
fn a_body_cut_off_is_not_decoded() {
    let (tx, rx) = std::sync::mpsc::channel();
    let mut cutter = BlockCutter::new(100, tx);
    cutter.push(body(50, true).as_bytes());
    drop(cutter);
    assert!(decode_blocks(rx, 2).unwrap().is_none());
}
