//! A synthetic logged run of the hand table of `iso230_2/tests.rs` (the ISO linear cycle
//! with overtravel, a servo lag that settles in each dwell, a pause at the turnaround)
//! must give back that table's figures.

use super::*;
use crate::metrology::iso230_2::tests::hand_table;

const PERIOD_S: f64 = 0.01;
const SPEED_MM_S: f64 = 50.0;
const KV: f64 = 20.0;

/// Builds the run: start dwell at −5 mm; per cycle the targets up (each a 1 s dwell), an
/// overtravel to +5 mm beyond the last with a 0.3 s pause, the targets down, an overtravel
/// to −5 mm without a pause. The reading is a first-order lag (kv = 20 1/s) of the command
/// plus the table's deviation of the visit being approached, plus `noise_mm` uniform noise.
fn run(noise_mm: f64) -> PositioningTrace {
    let table = hand_table();
    let m = table.targets_mm.len();
    let mut c = vec![-5.0; 100];
    let mut offsets = vec![0.0; 100];
    let go = |c: &mut Vec<f64>, offsets: &mut Vec<f64>, to: f64, dwell_s: f64, dev: f64| {
        let from = *c.last().unwrap();
        let steps = ((to - from).abs() / (SPEED_MM_S * PERIOD_S)).ceil() as usize;
        for k in 1..=steps {
            c.push(from + (to - from) * k as f64 / steps as f64);
            offsets.push(dev);
        }
        for _ in 0..(dwell_s / PERIOD_S).round() as usize {
            c.push(to);
            offsets.push(dev);
        }
    };
    let last = table.targets_mm[m - 1];
    for j in 0..5 {
        for i in 0..m {
            let p = table.targets_mm[i];
            go(&mut c, &mut offsets, p, 1.0, table.forward_mm[i][j] - p);
        }
        go(&mut c, &mut offsets, last + 5.0, 0.3, 0.0);
        for i in (0..m).rev() {
            let p = table.targets_mm[i];
            go(&mut c, &mut offsets, p, 1.0, table.backward_mm[i][j] - p);
        }
        if j < 4 {
            go(&mut c, &mut offsets, -5.0, 0.0, 0.0);
        }
    }
    let alpha = 1.0 - (-KV * PERIOD_S).exp();
    let mut x = c[0];
    let mut seed = 12345_u64;
    let measured = c
        .iter()
        .zip(&offsets)
        .map(|(&ck, &off)| {
            x += alpha * (ck - x);
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            x + off + 2.0 * noise_mm * u
        })
        .collect();
    PositioningTrace {
        period_s: PERIOD_S,
        commanded_mm: c,
        measured_mm: measured,
    }
}

#[test]
fn logged_run_gives_back_the_hand_table() {
    let ev = evaluate_trace(&run(0.0), &TraceOptions::default()).unwrap();
    let want = evaluate_table(&hand_table()).unwrap();
    assert_eq!(ev.table.targets_mm, hand_table().targets_mm);
    for (got, want) in [
        (ev.axis.a, want.a),
        (ev.axis.e, want.e),
        (ev.axis.m, want.m),
        (ev.axis.r, want.r),
        (ev.axis.b, want.b),
        (ev.axis.b_avg, want.b_avg),
    ] {
        // The settled tail starts where the lag's rest is inside the 10 nm floor; what is
        // left of it biases a reading by ~1 nm, a figure by at most a few nm.
        assert!((got - want).abs() < 5e-6, "got {got}, want {want}");
    }
    // The hand figures: R = 10 µm, E = 8 µm, A = 12 µm.
    assert!((ev.axis.r - 0.010).abs() < 5e-6 && (ev.axis.e - 0.008).abs() < 5e-6);
    assert_eq!(ev.used.len(), 50);
    // Ignored: the start dwell and the five pauses at the turnaround (approached upwards only).
    assert_eq!(ev.ignored.len(), 6, "{:?}", ev.ignored);
    assert!(ev.ignored[0].2.contains("start position"));
    assert!(
        ev.ignored[1..]
            .iter()
            .all(|d| d.2.contains("405 mm is approached only from the positive"))
    );
    // The settling (the lag of ~2.5 mm decaying at kv = 20 1/s to 10 nm takes ~0.6 s) is
    // left out of every reading.
    for r in &ev.used {
        assert!(r.settled[0] - r.dwell[0] >= 50, "{r:?}");
        assert!(r.settled[1] == r.dwell[1]);
    }
    // Directions: the first reading at 400 mm is the upward approach, the second (after the
    // overtravel to 405 mm and back) the downward one.
    let at400: Vec<&TraceReading> = ev.used.iter().filter(|r| r.target_mm == 400.0).collect();
    assert!(at400[0].forward && !at400[1].forward && at400[0].cycle == 0);
}

#[test]
fn noisy_run_reads_within_the_noise() {
    // ±0.5 µm uniform noise: each reading averages ~40 samples (σ ≈ 0.05 µm).
    let ev = evaluate_trace(&run(0.0005), &TraceOptions::default()).unwrap();
    assert_eq!(ev.used.len(), 50);
    assert!((ev.axis.e - 0.008).abs() < 3e-4, "E = {}", ev.axis.e);
    assert!((ev.axis.b - 0.004).abs() < 3e-4, "B = {}", ev.axis.b);
}

#[test]
fn bad_runs_are_refused() {
    let mut t = run(0.0);
    t.measured_mm.pop();
    assert!(matches!(
        evaluate_trace(&t, &TraceOptions::default()),
        Err(Error::LengthMismatch { .. })
    ));
    let mut t = run(0.0);
    t.period_s = 0.0;
    assert!(matches!(
        evaluate_trace(&t, &TraceOptions::default()),
        Err(Error::Invalid {
            field: "period_s",
            ..
        })
    ));
    // A ramp with no dwell has no targets.
    let t = PositioningTrace {
        period_s: 0.01,
        commanded_mm: (0..500).map(f64::from).collect(),
        measured_mm: (0..500).map(f64::from).collect(),
    };
    assert!(matches!(
        evaluate_trace(&t, &TraceOptions::default()),
        Err(Error::TooFew { .. })
    ));
}
