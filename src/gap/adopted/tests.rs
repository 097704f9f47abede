//! Unit tests of `crate::gap::adopted`.

use super::*;
use crate::gap::programs::{Program, generate};
use crate::gap::steps::compose;
use crate::motion::ServoAxis;
use rand::SeedableRng;

const PERIOD: f64 = 0.001;

fn servo(velocity_loop: bool) -> ServoAxis {
    ServoAxis {
        kv: 30.0,
        kff: 0.5,
        kp_v: velocity_loop.then_some(400.0),
        ti_v: velocity_loop.then_some(0.01),
        tc: None,
    }
}

fn infos(names: &[&str]) -> Vec<AxisInfo> {
    names
        .iter()
        .map(|n| AxisInfo {
            name: (*n).to_string(),
            velocity_loop: true,
        })
        .collect()
}

fn entry(f: &Fitted, names: &[String], plants: &[AxisPlant]) -> EffectEntry {
    EffectEntry {
        effect: f.effect().name().to_string(),
        params: f.params(names, plants, 2.0).into_iter().collect(),
    }
}

/// Every library effect, answered as a diagnosis answers it (`Fitted::params`) and stored,
/// adds to the linear simulation exactly what the diagnosis' own composition adds.
#[test]
fn a_diagnosis_answer_stored_adds_what_the_diagnosis_predicted() {
    let s = servo(true);
    let names = vec!["X".to_string(), "Y".to_string()];
    let plants: Vec<AxisPlant> = names
        .iter()
        .map(|n| AxisPlant::new(n, &s, PERIOD).unwrap())
        .collect();
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let cmd = generate(Program::Circle, 2, PERIOD, false, &mut rng);
    let linear: Vec<Vec<f64>> = plants.iter().zip(&cmd).map(|(p, c)| p.linear(c)).collect();
    let cases = [
        Fitted::CoulombFriction { f: vec![80.0, 0.0] },
        Fitted::Backlash {
            b: vec![0.02, 0.01],
            start: vec![-1.0, 0.5],
        },
        Fitted::ServoGainMismatch {
            kv: vec![27.0, 33.0],
        },
        Fitted::AxisSquareness {
            target: 1,
            source: 0,
            alpha: 60e-6,
        },
        Fitted::ScaleError {
            s: vec![300e-6, -150e-6],
        },
        Fitted::CyclicError {
            pitch: vec![5.0, 10.0],
            sin: vec![0.003, -0.001],
            cos: vec![-0.002, 0.004],
        },
        Fitted::ThermalDrift {
            rate: vec![2e-3, -1e-3],
            tau: 30.0,
        },
        Fitted::ThermalDrift {
            rate: vec![2e-3, 0.0],
            tau: f64::INFINITY,
        },
    ];
    let models: Vec<AxisModel<'_>> = names
        .iter()
        .map(|n| AxisModel {
            name: n,
            servo: &s,
            structure: None,
        })
        .collect();
    for f in &cases {
        let set = EffectSet {
            effects: vec![entry(f, &names, &plants)],
            source: None,
        };
        check(&set, &infos(&["X", "Y", "Z"])).unwrap();
        let stored = StoredEffects::new(&set, &infos(&["X", "Y"]), 3).unwrap();
        let got = stored.apply(&models, PERIOD, &cmd, &linear).unwrap();
        let want = compose(std::slice::from_ref(f), &plants, &cmd, &linear);
        let worst = got
            .iter()
            .flatten()
            .zip(want.iter().flatten())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let size = want
            .iter()
            .flatten()
            .zip(linear.iter().flatten())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            size > 1e-5,
            "{f:?} should change the simulation, changed {size}"
        );
        assert!(
            worst < 1e-9,
            "{f:?}: stored differs from the diagnosis by {worst} mm"
        );
        assert_eq!(stored.version(), 3);
    }
}

/// An effect on an axis the simulation does not have is not applied; the others are.
#[test]
fn an_effect_on_an_axis_not_simulated_is_left_out() {
    let s = servo(false);
    let set: EffectSet = serde_json::from_value(serde_json::json!({
        "effects": [{"effect": "scale_error", "params": {"x_ppm": 1000.0, "z_ppm": 5000.0}}]
    }))
    .unwrap();
    let stored = StoredEffects::new(&set, &infos(&["X", "Y", "Z"]), 1).unwrap();
    let models = [AxisModel {
        name: "X",
        servo: &s,
        structure: None,
    }];
    let cmd = vec![vec![0.0, 10.0, 20.0]];
    let got = stored.apply(&models, PERIOD, &cmd, &cmd).unwrap();
    assert_eq!(got, vec![vec![0.0, 10.01, 20.02]]);
}

/// The part of a set a program corrects in its points (scale, squareness, cyclic error,
/// backlash) is split from the rest; its geometric effects give at a point what the
/// simulation adds to a linear position there, and its backlash the play per axis.
#[test]
fn the_geometric_part_is_split_and_evaluated_at_a_point() {
    let s = servo(false);
    let set: EffectSet = serde_json::from_value(serde_json::json!({
        "effects": [
            {"effect": "scale_error", "params": {"x_ppm": 600.0, "y_ppm": -300.0}},
            {"effect": "axis_squareness", "params": {"y_per_x_rad": 2e-4}},
            {"effect": "cyclic_error", "params": {"z_pitch_mm": 5.0, "z_amplitude_mm": 0.003,
                "z_phase_rad": 0.4}},
            {"effect": "backlash", "params": {"x_mm": 0.02}}
        ]
    }))
    .unwrap();
    let stored = StoredEffects::new(&set, &infos(&["X", "Y", "Z"]), 3).unwrap();
    let (geo, rest) = stored.split_corrected();
    assert_eq!(
        geo.names(),
        ["scale_error", "axis_squareness", "cyclic_error", "backlash"]
    );
    assert!(rest.is_empty());
    assert_eq!(geo.backlash_mm(), [0.02, 0.0, 0.0]);
    let play = EffectSet {
        effects: set.effects[3..].to_vec(),
        source: None,
    };
    let play = StoredEffects::new(&play, &infos(&["X", "Y", "Z"]), 3).unwrap();
    assert_eq!(play.geometric_error_at([100.0, 50.0, -20.0]), [0.0; 3]);
    assert_eq!(play.drift_at(100.0), [0.0; 3]);
    let warm: EffectSet = serde_json::from_value(serde_json::json!({"effects": [
        {"effect": "thermal_drift", "params": {"y_rate_mm_s": 1e-4, "tau_s": 200.0}}]}))
    .unwrap();
    let warm = StoredEffects::new(&warm, &infos(&["X", "Y", "Z"]), 1).unwrap();
    let (corrected, rest) = warm.split_corrected();
    assert!(rest.is_empty());
    let d = corrected.drift_at(200.0)[1];
    assert!(
        (d - 1e-4 * 200.0 * (1.0 - (-1.0f64).exp())).abs() < 1e-12,
        "{d}"
    );
    let p = [100.0, 50.0, -20.0];
    let e = geo.geometric_error_at(p);
    let z = 0.003 * (std::f64::consts::TAU * -20.0 / 5.0 + 0.4).sin();
    let want = [600e-6 * 100.0, -300e-6 * 50.0 + 2e-4 * 100.0, z];
    for k in 0..3 {
        assert!(
            (e[k] - want[k]).abs() < 1e-12,
            "axis {k}: {} vs {}",
            e[k],
            want[k]
        );
    }
    // the same as the simulation adds to a linear run standing at p
    let models: Vec<AxisModel> = ["X", "Y", "Z"]
        .iter()
        .map(|n| AxisModel {
            name: n,
            servo: &s,
            structure: None,
        })
        .collect();
    let col: Vec<Vec<f64>> = p.iter().map(|&v| vec![v, v]).collect();
    let geometric = EffectSet {
        effects: set.effects[..3].to_vec(),
        source: None,
    };
    let geometric = StoredEffects::new(&geometric, &infos(&["X", "Y", "Z"]), 3).unwrap();
    let sim = geometric.apply(&models, PERIOD, &col, &col).unwrap();
    for k in 0..3 {
        assert!((sim[k][1] - p[k] - e[k]).abs() < 1e-12);
    }
}

fn refusal(v: serde_json::Value) -> String {
    let set: EffectSet = serde_json::from_value(serde_json::json!({ "effects": [v] })).unwrap();
    match check(&set, &infos(&["X", "Y", "Z"])) {
        Err(e) => e.to_string(),
        Ok(()) => panic!("accepted {set:?}"),
    }
}

/// Each refusal names the key and what to send.
#[test]
fn bad_bodies_are_refused_naming_the_key() {
    let cases = [
        (
            serde_json::json!({"effect": "gravity", "params": {"x_mm": 1.0}}),
            "not an effect that can be stored",
        ),
        (
            serde_json::json!({"effect": "backlash", "params": {"w_mm": 0.01}}),
            "backlash.params.w_mm: keys start with an axis of the machine (X, Y, Z)",
        ),
        (
            serde_json::json!({"effect": "backlash", "params": {"x_width": 0.01}}),
            "backlash.params.x_width: unknown key",
        ),
        (
            serde_json::json!({"effect": "backlash", "params": {"x_mm": -0.01}}),
            "out of range",
        ),
        (
            serde_json::json!({"effect": "axis_squareness", "params": {"urad": 20.0}}),
            "name the axes",
        ),
        (
            serde_json::json!({"effect": "coulomb_friction",
                               "params": {"x_velocity_deficit_mm_s": 0.1}}),
            "axis X has a velocity loop",
        ),
        (
            serde_json::json!({"effect": "scale_error", "params": {}}),
            "has no params",
        ),
    ];
    for (body, want) in cases {
        let got = refusal(body.clone());
        assert!(got.contains(want), "{body}: got {got:?}, want {want:?}");
    }
}
