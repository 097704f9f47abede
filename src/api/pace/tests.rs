//! Unit tests of the body pace: the allowance, the sentences, and bodies read at a good
//! rate, too slowly, stalled, small on a slow link (the HTTP behaviour: tests/api/stalled.rs).

use std::time::Duration;

use super::*;

const PACE: Pace = Pace {
    stall: Duration::from_secs(30),
    min_rate: 64 * 1024,
    grace: RATE_GRACE,
};

#[test]
fn the_allowance_is_the_grace_plus_the_bytes_at_the_minimum_rate() {
    // 1 MiB at 64 KiB/s: 16 s plus the 2 s grace.
    assert_eq!(PACE.allowance(1 << 20), Some(Duration::from_secs(18)));
    // A small body gets the stall time in total, however slow.
    assert_eq!(PACE.allowance(1000), Some(Duration::from_secs(30)));
    assert_eq!(
        PACE.allowance(SMALL_BODY_BYTES),
        Some(Duration::from_secs(30))
    );
    // Just past the small size the rate applies: 2 s + 1 s.
    let past = PACE.allowance(SMALL_BODY_BYTES + 1).unwrap();
    assert!((past.as_secs_f64() - 3.0).abs() < 1e-3, "{past:?}");
    let off = Pace {
        min_rate: 0,
        ..PACE
    };
    assert_eq!(off.allowance(1 << 30), None);
}

#[test]
fn the_sentences_name_the_setting_missed() {
    let stall = sentence(&PACE, Missed::Stall);
    assert!(
        stall.contains("no byte for 30 s (--body-timeout-s)"),
        "{stall}"
    );
    let slow = sentence(
        &PACE,
        Missed::Rate {
            bytes: 200 * 1024,
            waited: Duration::from_secs(10),
        },
    );
    assert!(slow.contains("20.0 KiB/s"), "{slow}");
    assert!(slow.contains("minimum of 64.0 KiB/s after 2 s"), "{slow}");
    assert!(slow.contains("--min-body-rate"), "{slow}");
}

/// Reads a body of `chunks` (pause before, length) through a [`PacedBody`]: the bytes
/// read, or the verdict.
async fn drain(pace: Pace, chunks: Vec<(Duration, usize)>) -> Result<u64, Missed> {
    use futures::StreamExt;
    let stream = futures::stream::iter(chunks).then(|(pause, len)| async move {
        tokio::time::sleep(pause).await;
        Ok::<_, std::io::Error>(bytes::Bytes::from(vec![b' '; len]))
    });
    let verdict = Arc::new(Mutex::new(None));
    let body = PacedBody {
        inner: axum::body::Body::from_stream(stream),
        pace,
        bytes: 0,
        waited: Duration::ZERO,
        since: None,
        timer: Box::pin(tokio::time::sleep(Duration::ZERO)),
        verdict: verdict.clone(),
    };
    let mut data = axum::body::Body::new(body).into_data_stream();
    let mut n = 0;
    while let Some(chunk) = data.next().await {
        match chunk {
            Ok(c) => n += c.len() as u64,
            Err(_) => return Err(verdict.lock().unwrap().expect("a verdict with the error")),
        }
    }
    Ok(n)
}

/// A pace ten times quicker than the service's, so that the test takes a second.
const QUICK: Pace = Pace {
    stall: Duration::from_secs(2),
    min_rate: 1 << 20,
    grace: Duration::from_millis(200),
};

#[tokio::test]
async fn a_body_at_a_good_rate_passes_and_a_slow_or_stalled_one_does_not() {
    let ms = Duration::from_millis;
    // 1 MiB at about 4 MiB/s (64 KiB every 15 ms): passes.
    assert_eq!(
        drain(QUICK, vec![(ms(15), 64 * 1024); 16]).await,
        Ok(1 << 20)
    );
    // At 320 KiB/s (32 KiB every 100 ms): cut off once past the small size, on the rate.
    match drain(QUICK, vec![(ms(100), 32 * 1024); 32]).await {
        Err(Missed::Rate { bytes, waited }) => {
            assert!(bytes > SMALL_BODY_BYTES && bytes < 256 * 1024, "{bytes}");
            let allowed = QUICK.allowance(bytes).unwrap();
            assert!(
                waited >= allowed && waited < allowed + ms(300),
                "{waited:?} {allowed:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    // A small body on a slow link (1 KiB every 20 ms, 20 KiB) passes.
    assert_eq!(drain(QUICK, vec![(ms(20), 1024); 20]).await, Ok(20 * 1024));
    // A pause of the stall time ends any body (a long grace keeps the rate out of it).
    let stalled = Pace {
        stall: ms(300),
        grace: Duration::from_secs(5),
        ..QUICK
    };
    let pauses = vec![(Duration::ZERO, 1024), (ms(400), 1024)];
    assert_eq!(drain(stalled, pauses).await, Err(Missed::Stall));
    // Without a minimum rate only stalls count: the slow body passes.
    let off = Pace {
        min_rate: 0,
        ..QUICK
    };
    assert_eq!(
        drain(off, vec![(ms(100), 32 * 1024); 8]).await,
        Ok(256 * 1024)
    );
}
