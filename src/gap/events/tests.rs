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
    assert_eq!(spans[0].label, "X stop");
    assert_eq!(spans[0].axis, "X");
    assert_eq!(spans[0].start, 100);
    assert!((spans[0].share - 40.0 * 4.0 / (40.0 * 4.0 + 1.0)).abs() < 1e-12);
    assert!(
        spans[1].label == "X reversal" && spans[1].start == 200,
        "{spans:?}"
    );
}

/// A lag that sets in at each X reversal and persists until the next belongs to the span
/// that starts at the X reversal, although Y's zig-zag cuts the timeline into many spans.
#[test]
fn persisting_lag_goes_to_the_reversal_it_starts_at_not_to_other_axes_events() {
    // X: 0 -> 10 over 1000 samples, back over 1000; Y steps up 0.5 mm every 100 samples
    let n = 2000;
    let x: Vec<f64> = (0..n)
        .map(|i| {
            if i < 1000 {
                i as f64 * 0.01
            } else {
                (2000 - i) as f64 * 0.01
            }
        })
        .collect();
    let y: Vec<f64> = (0..n)
        .map(|i| {
            0.5 * (i / 100) as f64
                + if i % 100 >= 90 {
                    0.05 * (i % 100 - 90) as f64
                } else {
                    0.0
                }
        })
        .collect();
    // the X lag flips from -5 um to +5 um at the reversal (backlash of 10 um)
    let rx: Vec<f64> = (0..n)
        .map(|i| if i < 1000 { -0.005 } else { 0.005 })
        .collect();
    let ry = vec![0.0; n];
    let spans = rank_spans(&[x, y], &[rx, ry], &names(), 5);
    assert_eq!(spans[0].axis, "X", "{spans:?}");
    assert_eq!(spans[0].label, "X reversal", "{spans:?}");
    assert!((spans[0].start as i64 - 1000).abs() <= 1, "{spans:?}");
    assert!(spans[0].share > 0.5, "{spans:?}");
}
