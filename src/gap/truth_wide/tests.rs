//! Unit tests of `crate::gap::truth_wide`: each widened truth checked against its physics
//! (where a play's table rests, how a warm drift continues), the pair sizes and the extremes.

use super::*;
use crate::gap::programs::{Program, generate};
use crate::gap::truth::measure_at;
use rand::SeedableRng;

fn first_order(kv: f64) -> ServoAxis {
    ServoAxis {
        kv,
        kff: 0.0,
        kp_v: None,
        ti_v: None,
        tc: None,
    }
}

fn cascade(kv: f64) -> ServoAxis {
    ServoAxis {
        kv,
        kff: 0.6,
        kp_v: Some(kv * 12.0),
        ti_v: Some(0.012),
        tc: Some(0.0006),
    }
}

/// A play of 20 µm with its table at `s·b/2` from the motor: at rest the table sits there;
/// after a long move in + it lags the motor by b/2 (outside oracle: the play operator).
#[test]
fn a_play_starts_anywhere_in_its_gap() {
    let servo = vec![first_order(40.0)];
    // 0.2 s at rest at 100 mm, then 1 s ramp in + at 10 mm/s, then rest
    let mut c: Vec<f64> = vec![100.0; 200];
    c.extend((1..=1000).map(|i| 100.0 + 0.01 * i as f64));
    c.extend(vec![110.0; 800]);
    let cmd = vec![c];
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let clean = measure_at(&servo, &Truth::None, &cmd, 0.001, 0.0, 0.0, &mut rng);
    for s in [-1.0, -0.3, 0.6, 1.0] {
        let t = Truth::BacklashAt(vec![0.02], vec![s]);
        let m = measure_at(&servo, &t, &cmd, 0.001, 0.0, 0.0, &mut rng);
        let at_rest = m[0][100] - clean[0][100];
        assert!(
            (at_rest - s * 0.01).abs() < 1e-9,
            "s {s}: at rest {at_rest}"
        );
        let end = m[0][1999] - clean[0][1999];
        assert!((end + 0.01).abs() < 1e-6, "s {s}: after the move {end}");
    }
}

/// A warm block: the drift `D·(1 − e^{−t/τ})` continues from `t0`, so the block starts with
/// the offset `D·(1 − e^{−t0/τ})` already in it.
#[test]
fn thermal_drift_carries_on_warm() {
    let servo = vec![first_order(40.0), first_order(40.0)];
    let cmd = vec![vec![150.0; 1001], vec![80.0; 1001]];
    let (d, tau, t0) = (0.015, 0.7, 1.3);
    let t = Truth::Thermal(vec![d, -d], tau);
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let cold = measure_at(&servo, &t, &cmd, 0.001, 0.0, 0.0, &mut rng);
    let warm = measure_at(&servo, &t, &cmd, 0.001, t0, 0.0, &mut rng);
    let drift = |t: f64| d * (1.0 - (-t / tau).exp());
    assert!((cold[0][0] - 150.0).abs() < 1e-9);
    assert!((warm[0][0] - 150.0 - drift(t0)).abs() < 1e-9);
    assert!((warm[1][1000] - 80.0 + drift(t0 + 1.0)).abs() < 1e-9);
    // the validation block of a widened draw starts after the main one ended
    let servo2 = vec![cascade(35.0), cascade(40.0)];
    let prog = generate(Program::Circle, 2, 0.001, false, &mut rng);
    let w = draw_wide(7, &servo2, &prog, 0.001, &mut rng);
    let duration = (prog[0].len() - 1) as f64 * 0.001;
    assert!(matches!(w.main, Truth::Thermal(..)));
    assert!(w.validation_t0_s >= duration && w.validation_t0_s <= 1.3 * duration);
}

/// Pairs: two distinct library effects whose noise-free gaps are within 0.5–2 × of each other
/// (±10 % for the three secant corrections).
#[test]
fn pairs_are_two_effects_of_comparable_size() {
    let servo = vec![cascade(35.0), cascade(40.0)];
    let mut seen = std::collections::BTreeSet::new();
    for seed in 0..10 {
        let mut rng = rand::rngs::StdRng::seed_from_u64(100 + seed);
        let cmd = generate(Program::ALL[seed as usize % 5], 2, 0.001, false, &mut rng);
        let (pair, ratio) = draw_pair(&servo, &cmd, 0.001, &mut rng);
        let Truth::Pair(a, b) = &pair else {
            panic!("not a pair: {pair:?}")
        };
        let (ea, eb) = (a.effect().unwrap(), b.effect().unwrap());
        assert_ne!(ea, eb);
        seen.insert(ea);
        seen.insert(eb);
        let (ga, gb) = (
            gap_rms(&servo, a, &cmd, 0.001),
            gap_rms(&servo, b, &cmd, 0.001),
        );
        assert!((gb / ga - ratio).abs() < 1e-9);
        assert!((0.45..2.2).contains(&ratio), "{ea:?} {ga} vs {eb:?} {gb}");
        assert_eq!(pair.effects(), vec![ea, eb]);
    }
    assert!(seen.len() >= 5, "{seen:?}");
}

/// Extremes are far outside the usual draws: friction glitch 20–60 µm, play ≥ 0.3 mm, gain ×/÷ ≥ 2.5, scale
/// ≥ 3,000 ppm, squareness ≥ 2 mrad, cyclic ≥ 50 µm, drift ≥ 0.5 mm at the block's end.
#[test]
fn extremes_are_far_outside_the_usual_range() {
    let servo = vec![cascade(35.0), cascade(40.0), cascade(30.0)];
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let cmd = generate(Program::ZigZag, 3, 0.001, false, &mut rng);
    let duration = (cmd[0].len() - 1) as f64 * 0.001;
    for _ in 0..5 {
        for e in Effect::LIBRARY {
            let t = draw_extreme(e, &servo, &cmd, 0.001, &mut rng);
            assert_eq!(t.effect(), Some(e));
            let max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            match &t {
                Truth::BacklashAt(b, _) => assert!(max(b) >= 0.3 && max(b) <= 0.5),
                Truth::Mismatch(kv) => assert!(
                    kv.iter()
                        .zip(&servo)
                        .any(|(kv, s)| kv / s.kv >= 2.5 || kv / s.kv <= 0.4)
                ),
                Truth::Scale(s) => assert!(s.iter().all(|s| s.abs() >= 3000e-6)),
                Truth::Squareness(a, b, alpha) => assert!(a != b && alpha.abs() >= 2e-3),
                Truth::Cyclic(_, a, _) => assert!(max(a) >= 0.05),
                Truth::Thermal(dr, tau) => {
                    let end = max(dr) * (1.0 - (-duration / tau).exp());
                    assert!((0.5..=1.5 + 1e-9).contains(&end), "{end}");
                }
                Truth::Friction(_) => {
                    let a = measure_at(&servo, &t, &cmd, 0.001, 0.0, 0.0, &mut rng);
                    let b = measure_at(&servo, &Truth::None, &cmd, 0.001, 0.0, 0.0, &mut rng);
                    for k in 0..3 {
                        let peak = a[k]
                            .iter()
                            .zip(&b[k])
                            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                        assert!((0.018..0.066).contains(&peak), "axis {k} glitch {peak}");
                    }
                }
                other => panic!("unexpected {other:?}"),
            }
        }
    }
}

/// Cyclic errors reach every axis, a slow Z alone among them; a play is redrawn for the
/// validation block with its width kept.
#[test]
fn cyclic_on_any_axis_and_plays_redrawn() {
    let servo = vec![cascade(35.0), cascade(40.0), cascade(30.0)];
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let cmd = generate(Program::Circle, 3, 0.001, false, &mut rng);
    let (mut z, mut z_alone) = (0, 0);
    for _ in 0..60 {
        let Truth::Cyclic(_, a, _) =
            draw_single(Effect::CyclicError, &servo, &cmd, 0.001, &mut rng)
        else {
            panic!("not cyclic")
        };
        z += usize::from(a[2] > 0.0);
        z_alone += usize::from(a[0] == 0.0 && a[1] == 0.0 && a[2] > 0.0);
    }
    assert!(z >= 20 && z_alone >= 5, "Z {z}, Z alone {z_alone}");
    let t = draw_single(Effect::Backlash, &servo, &cmd, 0.001, &mut rng);
    let v = revalidate(&t, &mut rng);
    match (&t, &v) {
        (Truth::BacklashAt(b, s), Truth::BacklashAt(bv, sv)) => {
            assert_eq!(b, bv);
            assert_ne!(s, sv);
        }
        other => panic!("{other:?}"),
    }
}
