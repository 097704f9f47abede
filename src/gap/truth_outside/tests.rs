//! Unit tests of `crate::gap::truth_outside`: every plant is outside the library and moves
//! the measurement by its drawn size; diagnosed blind, a clear out-of-library gap is answered
//! `unexplained` with what its remainder is tied to.

use super::*;
use crate::gap::Effect;
use crate::gap::motion::{MotionBlock, MotionOptions, diagnose_motion};
use crate::gap::patterns::PatternKind;
use crate::gap::programs::{Program, generate};
use rand::SeedableRng;

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

fn program(p: Program, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    generate(p, 2, 0.001, false, &mut rng)
}

fn departure(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(a, b)| (a - b).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn every_kind_is_drawn_outside_the_library_and_moves_the_measurement() {
    let servo = servo();
    let cmd = program(Program::ZigZag, 1);
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let clean = measure_truth(&servo, &Truth::None, &cmd, 0.001, 0.0, &mut rng);
    let mut seen = std::collections::BTreeSet::new();
    for _ in 0..200 {
        let truth = draw(&servo, &mut rng);
        assert_eq!(truth.effect(), None, "{truth:?}");
        let label = format!("{truth:?}");
        let kind = label.strip_prefix("Outside(").unwrap_or(&label);
        seen.insert(kind.split(['(', ' ']).next().unwrap_or(kind).to_string());
        if seen.len() == KINDS {
            break;
        }
    }
    assert_eq!(seen.len(), KINDS, "{seen:?}");
    let plants = [
        Outside::StickSlip {
            axis: 0,
            static_mm: 0.01,
            kinetic_mm: 0.002,
        },
        Outside::Resonance {
            axis: 0,
            freq_hz: 15.0,
            damping: 0.05,
            peak_mm: 0.01,
        },
        Outside::BentScrew {
            axis: 0,
            lead_mm: 10.0,
            amplitude_mm: 0.01,
            phase: 0.0,
        },
        Outside::LooseGib {
            axis: 0,
            shift_mm: 0.01,
            tau_s: 0.05,
        },
        Outside::WrongKinematics { k: 2e-5 },
        Outside::SensorFault {
            axis: 1,
            at: 0.5,
            step_mm: 0.01,
            spikes: vec![(0.3, 0.02)],
        },
    ];
    for o in plants {
        let m = measure(&servo, &o, &cmd, 0.001, 0.0, &mut rng);
        let d = departure(&m, &clean);
        eprintln!("{o:?}: largest departure {:.2} µm", d * 1e3);
        assert!(d > 0.002 && d < 0.05, "{o:?}: {d}");
    }
}

/// Issue 23, item 2: a loose gib of X (Y shifts ±5 µm with X's direction) is no library
/// effect; the diagnosis answers `unexplained` and ties the remainder to X's direction.
/// Random moves in both axes (stop-and-go): on a zig-zag, X's direction is a function of the
/// Y pass and a cyclic error of Y fits it as well (the data cannot tell them apart).
#[test]
fn a_loose_gib_is_unexplained_and_tied_to_the_direction_of_x() {
    let servo = servo();
    let cmd = program(Program::StopAndGo, 4);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let gib = Outside::LooseGib {
        axis: 0,
        shift_mm: 0.01,
        tau_s: 0.03,
    };
    let meas = measure(&servo, &gib, &cmd, 0.001, 0.0003, &mut rng);
    let names = vec!["X".to_string(), "Y".to_string()];
    let block = MotionBlock {
        commanded: cmd,
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
    eprintln!(
        "goal: unexplained, tied to X's direction; ours {} (held-out share left {:.2}) {:#?}",
        d.verdict.name(),
        d.unexplained.heldout_share,
        d.unexplained.patterns
    );
    assert_eq!(d.verdict, Effect::Unexplained);
    assert!(d.unexplained.heldout_share > 0.5);
    let p = d.unexplained.patterns.first().expect("a pattern");
    assert_eq!(p.axis, "Y");
    assert_eq!(p.of.as_deref(), Some("X"));
    assert!(
        matches!(p.kind, PatternKind::Direction | PatternKind::Event),
        "{p:?}"
    );
}
