//! Tests of the thread splits: every split returns what the serial loop returns.

use super::*;

#[test]
fn zero_means_all_cores_and_others_pass_through() {
    assert!(resolve_threads(0) >= 1);
    assert_eq!(resolve_threads(3), 3);
    assert_eq!(chunk_len(10, 3, 1), 4);
    assert_eq!(chunk_len(10, 3, 8), 8);
}

#[test]
fn splits_match_the_serial_loop() {
    let items: Vec<u64> = (0..1000).collect();
    let sums = map_chunks(&items, 64, |off, c| (off, c.iter().sum::<u64>()));
    assert_eq!(sums.len(), 16);
    assert_eq!(sums[1].0, 64);
    assert_eq!(
        sums.iter().map(|s| s.1).sum::<u64>(),
        items.iter().sum::<u64>()
    );
    assert_eq!(
        map_chunks(&items[..3], 64, |off, c| (off, c.len())),
        [(0, 3)]
    );

    let mut out = vec![0u64; 500];
    let n = zip_chunks_mut(&items, 100, &mut out, 50, |x, y| {
        for (k, v) in y.iter_mut().enumerate() {
            *v = x[2 * k] + x[2 * k + 1];
        }
        y.len()
    });
    assert_eq!(n, vec![50; 10]);
    assert!((0..500).all(|k| out[k] == items[2 * k] + items[2 * k + 1]));

    for threads in [1, 3, 8] {
        let sq = map_dynamic(&items, threads, |x| x * x);
        assert!(sq.iter().zip(&items).all(|(s, x)| *s == x * x));
    }

    let (a, b) = join(|| 2 + 2, || 3 * 3);
    assert_eq!((a.unwrap(), b), (4, 9));
    let (bad, _) = join(|| -> u8 { panic!("background") }, || ());
    assert!(bad.is_err());
}
