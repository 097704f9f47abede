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

#[test]
fn lockstep_pairs_each_step_and_both_sides_see_the_same_pair() {
    // 2,000 steps, each side publishing (side, step): every exchange returns exactly that
    // step's pair, on both sides, whichever side arrives first.
    let l = Lockstep::<(usize, usize)>::new();
    let run = |side: usize| {
        let g = l.guard();
        let mut seen = Vec::new();
        for step in 0..2000 {
            if step % 97 == side {
                std::thread::yield_now(); // vary who arrives first
            }
            seen.push(l.exchange(side, step, (side, step)));
        }
        g.leave();
        seen
    };
    let (b, a) = join(|| run(1), || run(0));
    let b = b.unwrap();
    assert_eq!(a, b);
    for (step, pair) in a.iter().enumerate() {
        assert_eq!(*pair, ((0, step), (1, step)));
    }
}

#[test]
fn lockstep_side_that_panics_stops_the_other_instead_of_hanging() {
    let l = Lockstep::<u32>::new();
    let (other, ()) = join(
        || {
            let _g = l.guard();
            l.exchange(1, 0, 7);
            l.exchange(1, 1, 7) // side 0 never publishes step 1
        },
        || {
            let g = l.guard();
            l.exchange(0, 0, 3);
            drop(g); // leaves without `leave`: as a panic would
        },
    );
    assert!(
        other.is_err(),
        "the waiting side panicked rather than spinning forever"
    );
}

#[test]
fn lockstep_parks_a_side_whose_partner_is_late_and_pairs_still_match() {
    // Side 1 sleeps well past the spin before every 10th step (as a descheduled partner):
    // side 0 parks there instead of spinning, and is woken with the right pair.
    let l = Lockstep::<(usize, usize)>::new();
    let late = Lockstep::<u8>::SPIN * 20;
    let run = |side: usize| {
        let g = l.guard();
        let mut seen = Vec::new();
        for step in 0..100 {
            if side == 1 && step % 10 == 0 {
                std::thread::sleep(late);
            }
            seen.push(l.exchange(side, step, (side, step)));
        }
        g.leave();
        seen
    };
    let t0 = Instant::now();
    let (b, a) = join(|| run(1), || run(0));
    assert_eq!(a, b.unwrap());
    for (step, pair) in a.iter().enumerate() {
        assert_eq!(*pair, ((0, step), (1, step)));
    }
    assert!(l.parks() >= 10, "parks {}", l.parks());
    // Woken by the partner, not by the 1 ms safety timeout alone: 10 late steps of 1 ms each
    // take ~10 ms; far below the hang this test guards against.
    assert!(t0.elapsed() < Duration::from_secs(5));
}

#[test]
fn a_parked_side_sees_its_partner_abandon() {
    let l = Lockstep::<u32>::new();
    let (other, ()) = join(
        || {
            let _g = l.guard();
            l.exchange(1, 0, 7);
            l.exchange(1, 1, 7) // parks: side 0 never publishes step 1
        },
        || {
            let g = l.guard();
            l.exchange(0, 0, 3);
            std::thread::sleep(Lockstep::<u32>::SPIN * 40); // side 1 is parked by now
            drop(g);
        },
    );
    assert!(other.is_err(), "the parked side panicked rather than hang");
    assert!(l.parks() >= 1);
}

#[test]
fn runnable_count_is_read_from_loadavg() {
    assert_eq!(parse_runnable("0.52 0.31 0.20 3/181 8642\n"), Some(3));
    assert_eq!(parse_runnable("1.00 1.00 1.00 12/400 1"), Some(12));
    assert_eq!(parse_runnable("garbage"), None);
    assert_eq!(parse_runnable("0.1 0.1 0.1 x/5 1"), None);
    if let Some(r) = machine_runnable() {
        assert!(r >= 1, "the reader itself is running");
    }
}

#[test]
fn busy_counts_a_thread_once_and_scoped_threads_too() {
    // Other tests run beside this one and count themselves: compare with what this thread
    // sees before and inside, from inside scoped threads that hold on until all looked.
    let inside = || {
        let _outer = busy();
        let here = COUNTED.with(Cell::get);
        let inner = busy(); // nested: not counted again
        let nested_is_noop = !inner.counted;
        (here, nested_is_noop)
    };
    assert_eq!(inside(), (true, true));
    assert!(
        !COUNTED.with(Cell::get),
        "the guard's drop uncounts the thread"
    );
    // A scoped thread of `join` counts itself while it runs.
    let (seen, ()) = join(|| COUNTED.with(Cell::get), || ());
    assert!(seen.unwrap());
    // With as many busy threads as cores, no core is free (other tests running now only
    // lose a split, never bits).
    let cores = resolve_threads(0);
    BUSY.fetch_add(cores, Ordering::Relaxed);
    let free = core_free();
    BUSY.fetch_sub(cores, Ordering::Relaxed);
    assert!(!free);
}
