//! Unit tests of `crate::gap::steps`.

use super::*;
use crate::gap::plant::play;
use crate::gap::programs::{Program, generate};
use crate::motion::ServoAxis;
use rand::SeedableRng;

fn plants() -> Vec<AxisPlant> {
    let s = ServoAxis {
        kv: 30.0,
        kff: 0.5,
        kp_v: Some(400.0),
        ti_v: Some(0.01),
        tc: None,
    };
    vec![
        AxisPlant::new("X", &s, 0.001).unwrap(),
        AxisPlant::new("Y", &s, 0.001).unwrap(),
    ]
}

/// Backlash on X plus squareness of Y on X: fitted one after the other and then jointly,
/// both parameters come back and the gap vanishes.
#[test]
fn joint_fit_recovers_two_effects_added_one_after_another() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let plants = plants();
    let cmd = generate(Program::Circle, 2, 0.001, false, &mut rng);
    let base: Vec<Vec<f64>> = plants.iter().zip(&cmd).map(|(p, c)| p.linear(c)).collect();
    let meas = vec![
        play(&base[0], 0.012, 0.0),
        base[1]
            .iter()
            .zip(&base[0])
            .map(|(y, x)| y + 40e-6 * x)
            .collect(),
    ];
    let cache = SimCache::default();
    let p = Problem {
        plants: &plants,
        cmd: &cmd,
        meas: &meas,
        base: &base,
        cache: &cache,
    };
    let all = vec![1.0; cmd[0].len()];
    let before = Model::default().sse(&p, &all);
    let one = Model::default().with(&p, Effect::Backlash, &all, 0);
    let two = one.with(&p, Effect::AxisSquareness, &all, 2);
    let after = two.sse(&p, &all);
    eprintln!("{:?}\nsse {before:.3e} -> {after:.3e}", two.members);
    let Fitted::Backlash { b, .. } = &two.members[0] else {
        panic!("{:?}", two.members)
    };
    assert!((b[0] - 0.012).abs() < 0.0015, "{b:?}");
    let Fitted::AxisSquareness {
        target,
        source,
        alpha,
    } = two.members[1]
    else {
        panic!("{:?}", two.members)
    };
    assert_eq!((target, source), (1, 0));
    assert!((alpha - 40e-6).abs() < 4e-6, "{alpha}");
    assert!(after < 0.02 * before, "{before} {after}");
    // the composition used for validation blocks is the model's own prediction
    let pred = compose(&two.members, &plants, &cmd, &base);
    let own = two.predict(&base);
    assert!((pred[1][500] - own[1][500]).abs() < 1e-12);
}
