//! Unit tests of `crate::gap::usual`: the warnings' wording, and diagnoses of truths far
//! outside their usual sizes (drawn by the independent RK4 truth plant of `gap::truth`).

use super::*;
use crate::gap::motion::{MotionBlock, MotionOptions, diagnose_motion};
use crate::gap::truth::{Truth, measure};
use crate::gap::{Effect, Fitted};
use crate::motion::ServoAxis;
use rand::SeedableRng;

#[test]
fn grouped_prints_thousands_and_a_true_minus() {
    assert_eq!(grouped(-4006.2, 0), "−4,006");
    assert_eq!(grouped(1234567.891, 2), "1,234,567.89");
    assert_eq!(grouped(0.4, 3), "0.400");
    assert_eq!(grouped(-0.0001, 2), "0.00");
    assert_eq!(grouped(999.0, 0), "999");
}

#[test]
fn usual_sizes_give_no_warning_unusual_ones_say_why_and_where_to_look() {
    let servo = ServoAxis {
        kv: 30.0,
        kff: 0.0,
        kp_v: Some(400.0),
        ti_v: None,
        tc: None,
    };
    let plants = vec![AxisPlant::new("X", &servo, 0.001).unwrap()];
    let axes = vec!["X".to_string()];
    let w = |f: &Fitted| warnings(f, &axes, &plants, 10.0);
    assert!(w(&Fitted::ScaleError { s: vec![40e-6] }).is_empty());
    let scale = w(&Fitted::ScaleError {
        s: vec![-4006.2e-6],
    });
    assert_eq!(
        scale,
        [
            "scale error X −4,006 ppm: far above a machine's usual ±50 ppm; check the lead or \
          pitch parameter, the encoder resolution, or the measuring device's alignment"
        ]
    );
    assert!(
        w(&Fitted::Backlash {
            b: vec![0.02],
            start: vec![0.0]
        })
        .is_empty()
    );
    assert!(
        w(&Fitted::Backlash {
            b: vec![0.4],
            start: vec![0.0]
        })[0]
            .starts_with("backlash X 0.4000 mm: far above")
    );
    assert!(w(&Fitted::ServoGainMismatch { kv: vec![33.0] }).is_empty());
    assert!(w(&Fitted::ServoGainMismatch { kv: vec![90.0] })[0].contains("3.00×"));
    // 0.02 mm static lag through kp_v·kv = 12,000 1/s²
    assert!(w(&Fitted::CoulombFriction { f: vec![240.0] })[0].contains("0.0200 mm"));
    assert!(w(&Fitted::CoulombFriction { f: vec![60.0] }).is_empty());
}

fn servo() -> Vec<ServoAxis> {
    let s = ServoAxis {
        kv: 30.0,
        kff: 0.5,
        kp_v: Some(400.0),
        ti_v: Some(0.01),
        tc: Some(0.0006),
    };
    vec![s.clone(), s]
}

/// A zig-zag of the stock program generator: back-and-forth X passes with short Y steps
/// (command per axis, mm, 1 ms).
fn passes(seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    crate::gap::programs::generate(
        crate::gap::programs::Program::ZigZag,
        2,
        0.001,
        false,
        &mut rng,
    )
}

/// Issue 23, item 1: a truth far outside its effect's usual range (scale 5,000 ppm, backlash
/// 0.4 mm, gain 3×) is the verdict, with its size and the warning — no veto by size, and the
/// searches that stop at a bound (backlash 0.25 mm, gain 2×) widen once.
#[test]
fn truths_far_outside_their_usual_range_are_named_with_size_and_warning() {
    let servo = servo();
    let names = vec!["X".to_string(), "Y".to_string()];
    let cmd = passes(3);
    let cases = [
        (
            Truth::Scale(vec![5000e-6, 0.0]),
            Effect::ScaleError,
            "x_ppm",
            5000.0,
            "scale error X 4,9|scale error X 5,0",
        ),
        (
            Truth::Backlash(vec![0.4, 0.0], true),
            Effect::Backlash,
            "x_mm",
            0.4,
            "backlash X 0.3|backlash X 0.4",
        ),
        (
            Truth::Mismatch(vec![90.0, 30.0]),
            Effect::ServoGainMismatch,
            "x_kv_ratio",
            3.0,
            "servo gain X 2.9|servo gain X 3.0",
        ),
    ];
    let mut rng = rand::rngs::StdRng::seed_from_u64(23);
    for (truth, effect, param, size, warning) in cases {
        let meas = measure(&servo, &truth, &cmd, 0.001, 0.0003, &mut rng);
        let block = MotionBlock {
            commanded: cmd.clone(),
            measured: meas,
        };
        let d = diagnose_motion(
            &names,
            &servo,
            0.001,
            &block,
            None,
            &MotionOptions::default(),
        )
        .unwrap();
        let step = d.steps.first().expect("a step");
        let fitted = step
            .params
            .iter()
            .find(|(k, _)| k == param)
            .map(|p| p.1)
            .unwrap();
        eprintln!(
            "goal: {} named, {param} = {size}; ours {} {param} = {fitted:.4}, warnings {:?}",
            effect.name(),
            d.verdict.name(),
            step.warnings
        );
        assert_eq!(d.verdict, effect);
        assert!((fitted - size).abs() < 0.03 * size, "{fitted} vs {size}");
        assert!(
            step.warnings
                .iter()
                .any(|w| warning.split('|').any(|p| w.starts_with(p))
                    && w.contains("a machine's usual")),
            "{:?}",
            step.warnings
        );
        assert!(step.at_bound.is_empty());
        let listed = d
            .effects
            .iter()
            .find(|e| e.fitted.effect() == effect)
            .unwrap();
        assert_eq!(listed.warnings, step.warnings);
    }
}
