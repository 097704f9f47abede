//! Unit tests of `crate::gap::truth_clock`, against the analytic lag of a first-order loop.

use super::*;
use crate::gap::truth::{Truth, measure};
use crate::motion::ServoAxis;
use rand::SeedableRng;

const V: f64 = 20.0; // mm/s
const KV: f64 = 50.0; // 1/s

/// A 2 s ramp at `V` on a first-order loop without feed-forward: after the transient the
/// table lags the command by `V/kv` (an outside oracle: `dx/dt = kv·(v·t − x)`).
fn ramp_trace() -> Vec<Vec<f64>> {
    let servo = vec![ServoAxis {
        kv: KV,
        kff: 0.0,
        kp_v: None,
        ti_v: None,
        tc: None,
    }];
    let cmd = vec![
        (0..2001)
            .map(|i| V * i as f64 * 0.001)
            .collect::<Vec<f64>>(),
    ];
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    measure(&servo, &Truth::None, &cmd, 0.001, 0.0, &mut rng)
}

/// A log is stamped at its own rate, late by its delay: the sample stamped `t` holds the
/// position at `t − delay` (the ramp's `V·(t − delay − 1/kv)`).
#[test]
fn a_log_is_late_by_its_delay_and_sampled_at_its_rate() {
    let trace = ramp_trace();
    let spec = ClockSpec {
        delay_s: 0.013,
        period_s: 0.0025,
        jitter_s: 0.0,
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let log = resample(&trace, 0.001, &spec, 0.0, &mut rng);
    assert_eq!(log.t.len(), 801, "2 s at 2.5 ms");
    for w in log.t.windows(2) {
        assert!((w[1] - w[0] - 0.0025).abs() < 1e-12);
    }
    let mut worst = 0.0f64;
    for (t, x) in log.t.iter().zip(&log.measured[0]) {
        if *t > 0.3 {
            worst = worst.max((x - V * (t - 0.013 - 1.0 / KV)).abs());
        }
    }
    assert!(
        worst < 1e-6,
        "largest departure from the analytic ramp {worst} mm"
    );
}

/// Jitter moves the true sampling instants but not the stamps: the departure from the ramp at
/// the stamps has RMS ≈ V·jitter.
#[test]
fn jitter_is_in_the_values_not_in_the_stamps() {
    let trace = ramp_trace();
    let spec = ClockSpec {
        delay_s: 0.0,
        period_s: 0.002,
        jitter_s: 0.0002,
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let log = resample(&trace, 0.001, &spec, 0.0, &mut rng);
    let dev: Vec<f64> = log
        .t
        .iter()
        .zip(&log.measured[0])
        .filter(|(t, _)| **t > 0.3 && **t < 1.9)
        .map(|(t, x)| x - V * (t - 1.0 / KV))
        .collect();
    let rms = (dev.iter().map(|d| d * d).sum::<f64>() / dev.len() as f64).sqrt();
    let expected = V * 0.0002;
    assert!(
        (rms / expected - 1.0).abs() < 0.2,
        "rms {rms} mm, expected {expected} mm"
    );
}

/// Read naively (stamps as command time), the log is the trace shifted late by the delay:
/// `V·delay` behind on the ramp.
#[test]
fn the_naive_reading_lags_by_the_delay() {
    let trace = ramp_trace();
    let spec = ClockSpec {
        delay_s: 0.02,
        period_s: 0.004,
        jitter_s: 0.0,
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let log = resample(&trace, 0.001, &spec, 0.0, &mut rng);
    let naive = naive_on_command_clock(&log, 2001, 0.001);
    assert_eq!(naive[0].len(), 2001);
    for i in (400..1900).step_by(50) {
        let lag = trace[0][i] - naive[0][i];
        assert!((lag - V * 0.02).abs() < 1e-6, "sample {i}: {lag} mm");
    }
}

/// Drawn clocks stay in their documented ranges and never share the command's rate.
#[test]
fn drawn_clocks_are_in_range() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for _ in 0..500 {
        let c = draw_clock(0.001, &mut rng);
        let ratio = c.period_s / 0.001;
        assert!(
            (0.5..4.0).contains(&ratio) && (ratio - 1.0).abs() > 0.05,
            "{c:?}"
        );
        assert!((0.002..0.030).contains(&c.delay_s), "{c:?}");
        assert!(c.jitter_s >= 0.0 && c.jitter_s < 0.1 * c.period_s, "{c:?}");
    }
}
