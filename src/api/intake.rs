//! Reading a request body into a parser as it arrives: the body's chunks go through a short
//! channel to a blocking thread that reads them as a `std::io::BufRead`. A probe upload is
//! thereby held as its parsed arrays only, never as its text too (issue 25: 8 concurrent
//! 120 MiB uploads; BENCHMARKS.md, "Concurrent uploads").

use std::io::{BufRead, Read};

use axum::body::{Body, Bytes};
use futures::StreamExt;
use tokio::sync::mpsc;

use super::error::{ApiError, ApiResult};

/// Chunks in flight between the body and the parser (a few hundred KiB at most).
const CHANNEL_CHUNKS: usize = 8;

/// The blocking side: the body's bytes in order, ending where the body ends. A body that
/// failed (cut off, too slow) ends in an I/O error.
pub struct ChunkReader {
    rx: mpsc::Receiver<Result<Bytes, String>>,
    cur: Bytes,
    failed: bool,
}

impl ChunkReader {
    /// A reader of the chunks sent to `rx`.
    pub fn new(rx: mpsc::Receiver<Result<Bytes, String>>) -> Self {
        ChunkReader {
            rx,
            cur: Bytes::new(),
            failed: false,
        }
    }
}

impl BufRead for ChunkReader {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        while self.cur.is_empty() && !self.failed {
            match self.rx.blocking_recv() {
                Some(Ok(chunk)) => self.cur = chunk,
                Some(Err(e)) => {
                    self.failed = true;
                    return Err(std::io::Error::other(e));
                }
                None => break,
            }
        }
        Ok(&self.cur)
    }

    fn consume(&mut self, amt: usize) {
        let _ = self.cur.split_to(amt.min(self.cur.len()));
    }
}

impl Read for ChunkReader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let have = self.fill_buf()?;
        let n = have.len().min(buf.len());
        buf[..n].copy_from_slice(&have[..n]);
        self.consume(n);
        Ok(n)
    }
}

/// Runs `parse` on a blocking thread over the body as it arrives. A body that fails to
/// arrive is a 400 saying so (the pace and budget middleware answer 408, 413 or 503 instead
/// when theirs was the cause); otherwise the parser's own answer. A parser that stops early
/// (an error on line 3) stops the reading too: the rest of the body is never read.
pub async fn parse_streaming<T: Send + 'static>(
    body: Body,
    parse: impl FnOnce(ChunkReader) -> ApiResult<T> + Send + 'static,
) -> ApiResult<T> {
    let (tx, rx) = mpsc::channel(CHANNEL_CHUNKS);
    let parser = tokio::task::spawn_blocking(move || parse(ChunkReader::new(rx)));
    let mut chunks = body.into_data_stream();
    let mut body_error = None;
    while let Some(chunk) = chunks.next().await {
        let item = match chunk {
            Ok(c) if c.is_empty() => continue,
            Ok(c) => Ok(c),
            Err(e) => {
                let text = e.to_string();
                body_error = Some(text.clone());
                Err(text)
            }
        };
        let failed = item.is_err();
        if tx.send(item).await.is_err() || failed {
            break; // the parser is done (an early error), or the body failed
        }
    }
    drop(tx);
    let parsed = parser.await.map_err(ApiError::internal)?;
    match body_error {
        Some(e) => Err(ApiError::bad_request(format!(
            "could not read the request body: {e}"
        ))),
        None => parsed,
    }
}

#[cfg(test)]
mod tests;
