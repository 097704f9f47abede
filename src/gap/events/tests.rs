//! Unit tests of `crate::gap::events`.

use super::*;

fn names() -> Vec<String> {
    vec!["X".into(), "Y".into()]
}

#[test]
fn circle_is_cut_at_the_four_axis_reversals() {
    let n = 4000;
    let (x, y): (Vec<f64>, Vec<f64>) = (0..n)
        .map(|i| {
            let th = std::f64::consts::TAU * i as f64 / (n - 1) as f64;
            (100.0 + 30.0 * th.cos(), 50.0 + 30.0 * th.sin())
        })
        .unzip();
    let ev = motion_events(&[x, y], &names());
    let labels: Vec<&str> = ev.iter().map(|e| e.1.as_str()).collect();
    assert_eq!(labels, ["Y reversal", "X reversal", "Y reversal"], "{ev:?}");
    assert!((ev[0].0 as f64 - 1000.0).abs() < 3.0);
    assert!((ev[1].0 as f64 - 2000.0).abs() < 3.0);
}

#[test]
fn residual_after_a_stop_ranks_that_span_first_with_its_share() {
    // move, dwell, move back: the gap sits in the dwell
    let mut x: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
    x.extend(std::iter::repeat_n(9.9, 100));
    x.extend((0..100).map(|i| 9.9 - i as f64 * 0.1));
    let y = vec![0.0; 300];
    let mut rx = vec![0.0; 300];
    for r in rx.iter_mut().take(160).skip(120) {
        *r = 0.002;
    }
    rx[250] = 0.001;
    let spans = rank_spans(&[x, y.clone()], &[rx, y], &names(), 10);
    assert_eq!(spans[0].label, "stop");
    assert_eq!(spans[0].start, 100);
    assert!((spans[0].share - 40.0 * 4.0 / (40.0 * 4.0 + 1.0)).abs() < 1e-12);
    assert!(
        spans[1].label.contains("start") && spans[1].label.contains("X reversal"),
        "{spans:?}"
    );
}
