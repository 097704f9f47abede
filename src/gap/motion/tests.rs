//! Unit tests of `crate::gap::motion`.

#![allow(clippy::needless_range_loop)]
use super::*;
use crate::gap::truth::{Truth, measure};
use rand::SeedableRng;

fn servo() -> Vec<ServoAxis> {
    vec![
        ServoAxis {
            kv: 30.0,
            kff: 0.0,
            kp_v: Some(400.0),
            ti_v: Some(0.01),
            tc: Some(0.0006),
        },
        ServoAxis {
            kv: 30.0,
            kff: 0.0,
            kp_v: Some(400.0),
            ti_v: Some(0.01),
            tc: Some(0.0006),
        },
    ]
}

/// A circle of radius 20 mm about (200, 100) mm at 40 mm/s for 7 s (about 2.2 turns),
/// `dir` = +1 CCW, −1 CW, with 0.2 s speed ramps; returns the command per axis.
fn circle(dir: f64) -> Vec<Vec<f64>> {
    let (r, v, total) = (20.0, 40.0, 7.0);
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for i in 0..7001 {
        let t = i as f64 * 0.001;
        let s = if t < 0.2 {
            v * t * t / 0.4
        } else if t < total - 0.2 {
            v * (t - 0.1)
        } else {
            v * (total - 0.2) - v * (total - t).powi(2) / 0.4
        };
        let th = dir * s / r;
        x.push(200.0 + r * th.cos());
        y.push(100.0 + r * th.sin());
    }
    vec![x, y]
}

fn names() -> Vec<String> {
    vec!["X".into(), "Y".into()]
}

/// Orientation (deg) of the 2θ term of the radial deviation about the centre.
fn ellipse_angle(pos: &[Vec<f64>]) -> f64 {
    let (mut a, mut b) = (0.0, 0.0);
    // exactly one turn at constant speed: 2π·20/40 s
    for i in 1000..1000 + 3142 {
        let (dx, dy) = (pos[0][i] - 200.0, pos[1][i] - 100.0);
        let th = dy.atan2(dx);
        let dr = dx.hypot(dy) - 20.0;
        a += dr * (2.0 * th).cos();
        b += dr * (2.0 * th).sin();
    }
    0.5 * b.atan2(a).to_degrees()
}

#[test]
fn ballbar_mismatch_flips_between_cw_and_ccw_squareness_does_not() {
    let plants: Vec<AxisPlant> = servo()
        .iter()
        .map(|s| AxisPlant::new("X", s, 0.001).unwrap())
        .collect();
    let mismatch = Fitted::ServoGainMismatch {
        kv: vec![30.0, 36.0],
    };
    let square = Fitted::AxisSquareness {
        target: 0,
        source: 1,
        alpha: 200e-6,
    };
    let mut angles = Vec::new();
    for dir in [1.0, -1.0] {
        let cmd = circle(dir);
        let base: Vec<Vec<f64>> = plants.iter().zip(&cmd).map(|(p, c)| p.linear(c)).collect();
        let a_m = ellipse_angle(&mismatch.predict(&plants, &cmd, &base));
        let a_s = ellipse_angle(&square.predict(&plants, &cmd, &base));
        angles.push((a_m, a_s));
    }
    let ((m_ccw, s_ccw), (m_cw, s_cw)) = (angles[0], angles[1]);
    // both are 45° ellipses; only the mismatch one turns by 90° with the direction
    for a in [m_ccw, m_cw, s_ccw, s_cw] {
        assert!((a.abs() - 45.0).abs() < 3.0, "{angles:?}");
    }
    assert!(m_ccw * m_cw < 0.0, "mismatch must flip: {angles:?}");
    assert!(s_ccw * s_cw > 0.0, "squareness must not flip: {angles:?}");
}

#[test]
fn friction_spike_decays_backlash_step_persists_and_the_diagnosis_tells_them_apart() {
    let servo = servo();
    let cmd = circle(1.0);
    let plants: Vec<AxisPlant> = servo
        .iter()
        .map(|s| AxisPlant::new("X", s, 0.001).unwrap())
        .collect();
    let base: Vec<Vec<f64>> = plants.iter().zip(&cmd).map(|(p, c)| p.linear(c)).collect();
    // Y reverses at θ = 90° (sample ≈ 885): look at the Y residual after it
    let rev = (1..cmd[1].len() - 1)
        .find(|&i| cmd[1][i + 1] < cmd[1][i])
        .unwrap();
    let fr = Fitted::CoulombFriction {
        f: vec![200.0, 200.0],
    }
    .predict(&plants, &cmd, &base);
    let bl = Fitted::Backlash {
        b: vec![0.01, 0.01],
        start: vec![0.0, 0.0],
    }
    .predict(&plants, &cmd, &base);
    let res = |p: &[Vec<f64>], i: usize| (p[1][i] - base[1][i]).abs();
    let peak_f = (rev..rev + 150).map(|i| res(&fr, i)).fold(0.0, f64::max);
    assert!(peak_f > 0.002, "friction glitch {peak_f}");
    assert!(
        res(&fr, rev + 800) < 0.3 * peak_f,
        "friction must decay: {} vs {peak_f}",
        res(&fr, rev + 800)
    );
    assert!(
        (res(&bl, rev + 800) - 0.005).abs() < 1e-4,
        "backlash persists at b/2"
    );
    assert!((res(&bl, rev + 1500) - 0.005).abs() < 1e-4);

    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    for (truth, expected) in [
        (Truth::Friction(vec![200.0, 200.0]), Effect::CoulombFriction),
        (Truth::Backlash(vec![0.01, 0.006], true), Effect::Backlash),
    ] {
        let meas = measure(&servo, &truth, &cmd, 0.001, 0.0003, &mut rng);
        let block = MotionBlock {
            commanded: cmd.clone(),
            measured: meas,
        };
        let d = diagnose_motion(
            &names(),
            &servo,
            0.001,
            &block,
            None,
            &MotionOptions::default(),
        )
        .unwrap();
        assert_eq!(
            d.verdict,
            expected,
            "{:?}",
            d.effects
                .iter()
                .map(|e| (e.fitted.effect(), e.score))
                .collect::<Vec<_>>()
        );
        assert!(d.gap_after.rms < 0.5 * d.gap_before.rms);
        // the gap sits in the spans that begin at reversals
        let at_reversals: f64 = d
            .spans
            .iter()
            .filter(|s| s.label.contains("reversal"))
            .map(|s| s.share)
            .sum();
        assert!(at_reversals > 0.7, "{:?}", d.spans);
        if expected == Effect::CoulombFriction {
            assert!(d.spans[0].label.contains("reversal"), "{:?}", d.spans[0]);
        }
    }
}

#[test]
fn none_when_the_stored_model_is_right_and_validation_is_passed_through() {
    let servo = servo();
    let cmd = circle(-1.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let meas = measure(&servo, &Truth::None, &cmd, 0.001, 0.0004, &mut rng);
    let vcmd = circle(1.0);
    let vmeas = measure(&servo, &Truth::None, &vcmd, 0.001, 0.0004, &mut rng);
    let main = MotionBlock {
        commanded: cmd,
        measured: meas,
    };
    let val = MotionBlock {
        commanded: vcmd.clone(),
        measured: vmeas,
    };
    let d = diagnose_motion(
        &names(),
        &servo,
        0.001,
        &main,
        Some(&val),
        &MotionOptions::default(),
    )
    .unwrap();
    assert_eq!(d.verdict, Effect::None);
    assert_eq!(d.gap_after, d.gap_before);
    assert!(
        (d.gap_before.rms - 0.0004 * 2f64.sqrt()).abs() < 0.0001,
        "{:?}",
        d.gap_before
    );
    assert!((d.noise_mm - 0.0004).abs() < 0.0001, "{}", d.noise_mm);
    let v = d.validation.unwrap();
    assert_eq!(v.predicted_before, v.predicted_after);
    assert_eq!(v.predicted_before[0].len(), vcmd[0].len());
    assert_eq!(d.effects.len(), 7);
}

#[test]
fn rejects_bad_shapes_and_values_with_the_field_named() {
    let servo = servo();
    let ok = MotionBlock {
        commanded: vec![vec![0.0; 100]; 2],
        measured: vec![vec![0.0; 100]; 2],
    };
    let run = |b: &MotionBlock, p: f64| {
        diagnose_motion(&names(), &servo, p, b, None, &MotionOptions::default())
    };
    assert!(run(&ok, 0.001).is_ok());
    assert!(matches!(run(&ok, 0.0), Err(Error::Invalid { .. })));
    let mut short = ok.clone();
    short.measured[1].pop();
    assert!(
        matches!(run(&short, 0.001), Err(Error::Shape { field, .. }) if field == "commanded.measured")
    );
    let mut nan = ok.clone();
    nan.measured[0][7] = f64::NAN;
    assert!(matches!(
        run(&nan, 0.001),
        Err(Error::NonFinite { index: 7, .. })
    ));
    let tiny = MotionBlock {
        commanded: vec![vec![0.0; 5]; 2],
        measured: vec![vec![0.0; 5]; 2],
    };
    assert!(matches!(run(&tiny, 0.001), Err(Error::Shape { .. })));
    let bad_servo = vec![ServoAxis::first_order(-3.0, 0.0), servo[1].clone()];
    assert!(matches!(
        diagnose_motion(&names(), &bad_servo, 0.001, &ok, None, &MotionOptions::default()),
        Err(Error::Servo { axis, .. }) if axis == "X"
    ));
}

/// Issue 25 (same input, same bits): one diagnosis with its effect fits on one thread, on
/// two (a dynamic queue hands the effects out, and the shared re-simulation cache fills in
/// whatever order the threads reach it), and two diagnoses at once on two threads give the
/// same bits in every number (compared through `Debug`, which prints each f64 in its
/// shortest round-trip digits).
#[test]
fn diagnosis_is_bit_identical_on_one_thread_two_or_beside_another() {
    let servo = servo();
    let cmd = circle(1.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(29);
    let truth = Truth::Backlash(vec![0.008, 0.004], true);
    let meas = measure(&servo, &truth, &cmd, 0.001, 0.0003, &mut rng);
    let block = MotionBlock {
        commanded: cmd,
        measured: meas,
    };
    let run = |threads: usize| {
        let opts = MotionOptions {
            threads,
            ..MotionOptions::default()
        };
        let d = diagnose_motion(&names(), &servo, 0.001, &block, None, &opts).unwrap();
        format!("{d:?}")
    };
    let one = run(1);
    assert!(run(2) == one, "two threads differ from one");
    let (a, b) = std::thread::scope(|s| {
        let other = s.spawn(|| run(2));
        let here = run(1);
        (other.join().unwrap(), here)
    });
    assert!(a == one && b == one, "a diagnosis beside another differs");
}

/// Issue 40: a log that observes only some grid instants (125 Hz and 10 Hz loggers on the
/// 1 kHz grid) is judged against the noise of the instants it observed. A straightness error
/// (out of the library) well above the noise is `unexplained` at every rate; counting every
/// grid instant in the noise floor made it 8x and 100x too high and steered sparse logs away
/// from that verdict.
#[test]
fn a_sparse_log_is_judged_against_the_noise_of_its_own_samples() {
    let servo = servo();
    let cmd = circle(1.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let truth = Truth::Straightness(4e-5, 0.0);
    let meas = measure(&servo, &truth, &cmd, 0.001, 0.0003, &mut rng);
    let main = MotionBlock {
        commanded: cmd,
        measured: meas,
    };
    let n = main.commanded[0].len();
    for every in [1, 8, 100] {
        let observed: Vec<f64> = (0..n)
            .map(|i| if i % every == 0 { 1.0 } else { 0.0 })
            .collect();
        let opts = MotionOptions {
            observed: Some(observed),
            ..MotionOptions::default()
        };
        let d = diagnose_motion(&names(), &servo, 0.001, &main, None, &opts).unwrap();
        assert_eq!(
            d.verdict,
            Effect::Unexplained,
            "one sample in {every}: {:?}, left {:?}",
            d.steps
                .iter()
                .map(|s| s.fitted.effect())
                .collect::<Vec<_>>(),
            d.unexplained.heldout_share
        );
    }
}
