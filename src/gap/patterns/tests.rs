//! Unit tests of `crate::gap::patterns`: each planted shape comes back as its own kind.

use super::*;

fn names() -> Vec<String> {
    vec!["X".into(), "Y".into()]
}

/// X goes back and forth between 100 and 160 mm at speeds that change pass to pass (30, 45,
/// 20, 60 mm/s), dwelling 0.3 s at each end; Y creeps from 50 to 56 mm. 1 ms samples.
fn command() -> Vec<Vec<f64>> {
    let mut x = vec![100.0; 300];
    let speeds = [30.0, 45.0, 20.0, 60.0, 35.0, 50.0, 25.0, 40.0];
    for (k, v) in speeds.iter().enumerate() {
        let (a, b) = if k % 2 == 0 {
            (100.0, 160.0)
        } else {
            (160.0, 100.0)
        };
        let steps = (60.0 / v / 0.001) as usize;
        for i in 1..=steps {
            x.push(a + (b - a) * i as f64 / steps as f64);
        }
        x.extend(std::iter::repeat_n(b, 300));
    }
    let n = x.len();
    let y = (0..n).map(|i| 50.0 + 6.0 * i as f64 / n as f64).collect();
    vec![x, y]
}

fn noise(n: usize, seed: u64) -> Vec<f64> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    (0..n).map(|_| rng.random_range(-0.0005..0.0005)).collect()
}

fn top(found: &[Pattern]) -> &Pattern {
    eprintln!("{found:#?}");
    found.first().expect("a pattern")
}

#[test]
fn a_shift_with_x_direction_on_y_is_tied_to_direction_of_x() {
    let cmd = command();
    let n = cmd[0].len();
    let mut dir = 1.0;
    let ry: Vec<f64> = (0..n)
        .zip(noise(n, 1))
        .map(|(i, e)| {
            if i + 1 < n && cmd[0][i + 1] != cmd[0][i] {
                dir = (cmd[0][i + 1] - cmd[0][i]).signum();
            }
            0.006 * dir + e
        })
        .collect();
    let rx = noise(n, 2);
    let found = patterns(&[rx, ry], &cmd, &cmd, &names(), 0.001);
    let p = top(&found);
    assert_eq!(p.kind, PatternKind::Direction);
    assert_eq!((p.axis.as_str(), p.of.as_deref()), ("Y", Some("X")));
    assert!((p.amplitude - 0.006).abs() < 0.0005, "{p:?}");
    assert!(p.explained > 0.8, "{p:?}");
}

#[test]
fn a_sawtooth_along_x_is_periodic_in_position_with_its_period() {
    let cmd = command();
    let n = cmd[0].len();
    let rx: Vec<f64> = cmd[0]
        .iter()
        .zip(noise(n, 3))
        .map(|(x, e)| 0.008 * ((x / 4.0).rem_euclid(1.0) - 0.5) + e)
        .collect();
    let found = patterns(&[rx, noise(n, 4)], &cmd, &cmd, &names(), 0.001);
    let p = top(&found);
    assert_eq!(p.kind, PatternKind::PeriodicPosition);
    assert_eq!(p.of.as_deref(), Some("X"));
    assert!((p.period_mm.unwrap() - 4.0).abs() < 0.1, "{p:?}");
    assert!(p.explained > 0.7, "{p:?}");
}

#[test]
fn ringing_after_each_x_reversal_is_tied_to_the_reversal() {
    let cmd = command();
    let n = cmd[0].len();
    let events = axis_events(&cmd, 0, "X");
    let mut rx = noise(n, 5);
    for (at, label) in &events {
        if !label.ends_with("reversal") {
            continue;
        }
        let dir = (cmd[0][at + 2] - cmd[0][*at]).signum();
        for j in 0..400.min(n - at) {
            let t = j as f64 * 0.001;
            rx[at + j] += dir * 0.01 * (-t / 0.08).exp() * (std::f64::consts::TAU * 25.0 * t).sin();
        }
    }
    let found = patterns(&[rx, noise(n, 6)], &cmd, &cmd, &names(), 0.001);
    let p = top(&found);
    assert_eq!(p.kind, PatternKind::Event);
    assert_eq!(p.event.as_deref(), Some("reversal"));
    assert!(p.explained > 0.6, "{p:?}");
}

#[test]
fn lost_counts_are_a_jump_at_their_time() {
    let cmd = command();
    let n = cmd[0].len();
    let rx: Vec<f64> = (0..n)
        .zip(noise(n, 7))
        .map(|(i, e)| if i >= 5000 { 0.012 } else { 0.0 } + e)
        .collect();
    let found = patterns(&[rx, noise(n, 8)], &cmd, &cmd, &names(), 0.001);
    let jump = found
        .iter()
        .find(|p| p.kind == PatternKind::Jump)
        .expect("a jump");
    assert!((jump.at_s.unwrap() - 5.0).abs() < 0.01, "{jump:?}");
    assert!((2.0 * jump.amplitude - 0.012).abs() < 0.001, "{jump:?}");
}

#[test]
fn noise_alone_has_no_pattern() {
    let cmd = command();
    let n = cmd[0].len();
    let found = patterns(&[noise(n, 9), noise(n, 10)], &cmd, &cmd, &names(), 0.001);
    assert!(found.is_empty(), "{found:?}");
}
