//! Unit tests of parsing a body as it arrives: chunked CSV and JSON read as the whole body
//! does, an early refusal stops the reading, a failed body is a read error.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::*;
use crate::api::upload::{
    ProbeData, parse_csv_upload, parse_json_upload, read_csv_upload, read_json_upload,
};

/// A body of `text` cut into chunks of `size` bytes (cuts fall inside numbers and lines);
/// `sent` counts the chunks taken from it.
fn chunked(text: &str, size: usize, sent: Arc<AtomicUsize>) -> Body {
    let chunks: Vec<Result<Bytes, std::io::Error>> = text
        .as_bytes()
        .chunks(size)
        .map(|c| Ok(Bytes::copy_from_slice(c)))
        .collect();
    Body::from_stream(futures::stream::iter(chunks).inspect(move |_| {
        sent.fetch_add(1, Ordering::Relaxed);
    }))
}

fn csv_text(rows: usize) -> String {
    let mut csv = String::from("\u{feff}Point;X [mm];Y [mm];Z [mm]\r\n# exported\r\n");
    for k in 0..rows {
        csv.push_str(&format!("P{k};{},5;{};-0,00{}\r\n", k % 7, k / 7, k % 10));
    }
    csv
}

#[tokio::test]
async fn a_streamed_csv_reads_as_the_whole_body_does() {
    let csv = csv_text(500);
    let whole = parse_csv_upload(csv.as_bytes()).unwrap();
    for size in [1, 7, 64, 4096] {
        let body = chunked(&csv, size, Arc::default());
        let got = parse_streaming(body, move |r| read_csv_upload(r, Some(500)))
            .await
            .unwrap();
        assert_eq!(got, whole, "chunks of {size}");
    }
}

#[tokio::test]
async fn a_streamed_json_reads_as_the_whole_body_does() {
    let pts: Vec<[f64; 3]> = (0..300)
        .map(|k| [k as f64 * 0.25, -(k as f64) / 3.0, 1e-3 * k as f64])
        .collect();
    let json = serde_json::json!({"id": "run-1", "points": pts}).to_string();
    let whole = parse_json_upload(json.as_bytes()).unwrap();
    assert_eq!(whole.1.as_deref(), Some("run-1"));
    for size in [1, 13, 4096] {
        let body = chunked(&json, size, Arc::default());
        let got = parse_streaming(body, read_json_upload).await.unwrap();
        assert_eq!(got, whole, "chunks of {size}");
    }
    // Errors are worded as for a whole body.
    let bad = r#"{"deviations": [0.1, "x"]}"#;
    let whole = parse_json_upload(bad.as_bytes())
        .unwrap_err()
        .detail()
        .to_string();
    let streamed = parse_streaming(chunked(bad, 5, Arc::default()), read_json_upload)
        .await
        .unwrap_err();
    assert_eq!(streamed.detail(), whole);
    let empty = parse_streaming(chunked("", 5, Arc::default()), read_json_upload)
        .await
        .unwrap_err();
    assert!(
        empty.detail().contains("the request body is empty"),
        "{}",
        empty.detail()
    );
}

#[tokio::test]
async fn a_csv_with_more_rows_than_the_grid_is_refused_without_reading_the_rest() {
    let csv = csv_text(20_000);
    let sent = Arc::new(AtomicUsize::new(0));
    let body = chunked(&csv, 1024, sent.clone());
    let total = csv.len().div_ceil(1024);
    let e = parse_streaming(body, move |r| read_csv_upload(r, Some(100)))
        .await
        .unwrap_err();
    assert!(
        e.detail().contains("more than 100 entries"),
        "{}",
        e.detail()
    );
    assert!(
        e.detail().contains("CSV line 103 is entry 101"),
        "{}",
        e.detail()
    );
    let read = sent.load(Ordering::Relaxed);
    assert!(read < total / 10, "{read} of {total} chunks read");
}

#[tokio::test]
async fn a_body_that_fails_is_a_read_error_not_a_parse_error() {
    let chunks: Vec<Result<Bytes, std::io::Error>> = vec![
        Ok(Bytes::from_static(b"deviation\n0.1\n0.")),
        Err(std::io::Error::other("connection reset")),
    ];
    let body = Body::from_stream(futures::stream::iter(chunks));
    let e = parse_streaming(body, move |r| read_csv_upload(r, None))
        .await
        .unwrap_err();
    assert!(
        e.detail().starts_with("could not read the request body"),
        "{}",
        e.detail()
    );
    assert!(e.detail().contains("connection reset"), "{}", e.detail());
    // A whole body: the parser's answer.
    let body = Body::from("deviation\n0.1\n0.2\n");
    let got = parse_streaming(body, move |r| read_csv_upload(r, None))
        .await
        .unwrap();
    assert_eq!(got, ProbeData::Deviations(vec![0.1, 0.2]));
}
