//! Tests of the machine definition: every refusal names its field (and, for an unknown key,
//! the keys allowed); every accepted definition simulates.

use serde_json::{Value, json};

use super::*;
use crate::motion::{Machine, machine_for_simulation, servo_axes};

/// Definitions the service accepts: the HTTP contract's body, every extension, the demo's and the
/// tests' machines.
pub(crate) fn accepted() -> Vec<Value> {
    let full = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    vec![
        json!({"kinematics": "xyz", "axes": {"X": {"kv": 30}, "Y": {"kv": 30}, "Z": {"kv": 25}}}),
        json!({"name": "Demo 3-axis vertical mill", "kinematics": "xyz",
               "axes": {"X": full, "Y": full, "Z": full}}),
        json!({"name": "test mill", "kinematics": "xyz",
               "axes": {"X": {"kv": 30.0, "kff": 0.5}, "Y": {"kv": 30.0},
                        "Z": {"kv": 25.0, "kp_v": 300.0, "ti_v": 0.01, "tc": 0.001}}}),
        json!({"kinematics": "xyz", "rapid_mm_min": 20000, "name": null,
               "axes": {"X": {"kv": 30, "kff": null, "max_vel": 1e6, "max_accel": 1e7, "max_jerk": 1e10},
                        "Y": {"kv": 10000}, "Z": {"kv": 0.5, "kff": 1}}}),
        json!({"kinematics": "xyzac_table",
               "geometry": {"a_axis_origin": [0, 0, -100], "c_axis_origin": [0, 0, -100], "tool_length": 80},
               "axes": {
                   "X": {"kv": 30, "physical": {"motor_inertia_kg_m2": 0.001, "velocity_gain_nm_s_per_rad": 0.5,
                         "current_bandwidth_hz": 1000, "lead_mm": 10, "table_mass_kg": 200,
                         "axial_stiffness_n_per_um": 150}},
                   "Y": {"kv": 30}, "Z": {"kv": 30}, "A": {"kv": 20},
                   "C": {"kv": 20, "physical": {"motor_inertia_kg_m2": 0.002, "velocity_gain_nm_s_per_rad": 1.0,
                         "gear_ratio": 90, "table_inertia_kg_m2": 2.0}}}}),
        json!({"kinematics": "xyzac_table",
               "axes": {"X": full, "Y": full, "Z": full,
                        "A": {"kv": 25.0, "kff": 0.6, "kp_v": 300.0, "ti_v": 0.02, "tc": 0.0008},
                        "C": {"kv": 25.0, "kff": 0.6, "kp_v": 300.0, "ti_v": 0.02, "tc": 0.0008}}}),
        json!({"kinematics": "xyz", "axes": {"X": full, "Y": full, "Z": full},
               "controller": {"kind": "linuxcnc"}}),
        json!({"kinematics": "xyz", "axes": {"X": full, "Y": full, "Z": full},
               "controller": {"kind": "grbl", "block_rate_hz": 400, "lookahead_blocks": 15,
                              "segment_cap": false}}),
    ]
}

/// Definitions the service refuses, with a text the 400 must contain (the field's path).
pub(crate) fn refused() -> Vec<(Value, &'static str)> {
    let xy = |x: Value| json!({"kinematics": "xyz", "axes": {"X": x}});
    vec![
        (json!({"kinematics": "xyz", "colour": "red"}), "colour"),
        (xy(json!({"kv": 30, "inertia_kg": 120})), "inertia_kg"),
        (xy(json!({"kv": 0})), "axes.X.kv"),
        (xy(json!({"kv": -1})), "axes.X.kv"),
        (xy(json!({"kv": 1e300})), "axes.X.kv"),
        (xy(json!({"kv": 20000})), "axes.X.kv"),
        (xy(json!({"kv": "fast"})), "axes.X.kv"),
        (xy(json!({"kff": 0.5})), "kv"),
        (xy(json!({"kv": 30, "kff": 1.5})), "axes.X.kff"),
        (xy(json!({"kv": 30, "kff": -0.1})), "axes.X.kff"),
        (xy(json!({"kv": 30, "tc": -0.001})), "axes.X.tc"),
        (xy(json!({"kv": 30, "tc": 5})), "axes.X.tc"),
        (xy(json!({"kv": 30, "kp_v": 0})), "axes.X.kp_v"),
        (xy(json!({"kv": 30, "kp_v": 1e9})), "axes.X.kp_v"),
        (xy(json!({"kv": 30, "ti_v": 1e-9})), "axes.X.ti_v"),
        (xy(json!({"kv": 30, "max_vel": 0})), "axes.X.max_vel"),
        (xy(json!({"kv": 30, "max_accel": -5})), "axes.X.max_accel"),
        (xy(json!({"kv": 30, "max_jerk": 1e300})), "axes.X.max_jerk"),
        // unstable: a slow current loop under a stiff velocity loop
        (
            xy(json!({"kv": 9000, "kp_v": 90000, "ti_v": 0.00001, "tc": 0.1})),
            "axes.X",
        ),
        (
            xy(json!({"kv": 30, "physical": {"motor_inertia_kg_m2": 0.001, "mass": 3}})),
            "mass",
        ),
        (
            xy(json!({"kv": 30, "physical": {"motor_inertia_kg_m2": -1}})),
            "axes.X.physical.motor_inertia_kg_m2",
        ),
        (
            xy(
                json!({"kv": 30, "physical": {"motor_inertia_kg_m2": 0.001, "velocity_gain_nm_s_per_rad": 0.5}}),
            ),
            "lead_mm",
        ),
        (
            json!({"kinematics": "xyz", "axes": {"X": {"kv": 30}, "A": {"kv": 30}}}),
            "axes.A",
        ),
        (json!({"kinematics": "xyz", "axes": {"Q": {"kv": 30}}}), "Q"),
        (json!({"kinematics": "hexapod"}), "hexapod"),
        (json!({"axes": {}}), "kinematics"),
        (json!([1, 2]), "object"),
        (json!(null), "object"),
        (json!({"kinematics": "xyz", "axes": {"X": [30]}}), "axes.X"),
        (
            json!({"kinematics": "xyz", "axes": {"X": {"kv": 30, "physical": [1]}}}),
            "axes.X.physical",
        ),
        (
            json!({"kinematics": "xyzac_table", "geometry": [0]}),
            "geometry",
        ),
        (json!({"kinematics": "xyz", "name": 5}), "name"),
        (json!({"kinematics": "xyz", "axes": [1]}), "axes"),
        (
            json!({"kinematics": "xyz", "rapid_mm_min": 0}),
            "rapid_mm_min",
        ),
        (
            json!({"kinematics": "xyz", "geometry": {"tool_length": 80}}),
            "geometry",
        ),
        (
            json!({"kinematics": "xyzac_table", "geometry": {"c_offset": [0, 0, 100]}}),
            "c_offset",
        ),
        (
            json!({"kinematics": "xyzac_table", "geometry": {"tool_length": 1e9}}),
            "geometry.tool_length",
        ),
        (
            json!({"kinematics": "xyz", "controller": "linuxcnc"}),
            "controller",
        ),
        (
            json!({"kinematics": "xyz", "controller": {"kind": "mach3"}}),
            "controller.kind",
        ),
        (json!({"kinematics": "xyz", "controller": {}}), "kind"),
        (
            json!({"kinematics": "xyz", "controller": {"kind": "grbl", "block_rate_hz": 0}}),
            "controller.block_rate_hz",
        ),
        (
            json!({"kinematics": "xyz", "controller": {"kind": "grbl", "lookahead_blocks": 0}}),
            "controller.lookahead_blocks",
        ),
        (
            json!({"kinematics": "xyz", "controller": {"kind": "grbl", "lookahead_blocks": 2.5}}),
            "controller.lookahead_blocks",
        ),
        (
            json!({"kinematics": "xyz", "controller": {"kind": "grbl", "buffer": 16}}),
            "buffer",
        ),
    ]
}

#[test]
fn refusals_name_the_field() {
    for (def, field) in refused() {
        let e = MachineDef::from_value(&def).expect_err(&def.to_string());
        assert!(
            matches!(e, Error::BadDefinition { .. }),
            "{def}: {e:?} is not a BadDefinition"
        );
        assert!(
            e.to_string().contains(field),
            "{def}: '{e}' lacks '{field}'"
        );
        let bytes = serde_json::to_vec(&def).unwrap();
        let e2 = MachineDef::from_slice(&bytes).unwrap_err().to_string();
        assert!(
            e2.starts_with(&e.to_string()),
            "bytes: '{e2}' vs value: '{e}'"
        );
    }
}

#[test]
fn an_unknown_key_is_named_with_the_keys_allowed() {
    let e = MachineDef::from_value(
        &json!({"kinematics": "xyz", "axes": {"X": {"kv": 30, "inertia_kg": 1}}}),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("axes.X") && e.contains("inertia_kg"), "{e}");
    for key in ["kv", "kff", "kp_v", "ti_v", "tc", "max_vel", "physical"] {
        assert!(e.contains(key), "{e} lacks {key}");
    }
    let e = MachineDef::from_value(&json!({"kinematics": "xyz", "colour": 1}))
        .unwrap_err()
        .to_string();
    for key in [
        "colour",
        "name",
        "kinematics",
        "axes",
        "geometry",
        "rapid_mm_min",
    ] {
        assert!(e.contains(key), "{e} lacks {key}");
    }
}

#[test]
fn a_number_json_cannot_hold_is_named_by_its_path() {
    let body = br#"{"kinematics": "xyz", "axes": {"X": {"kv": 1e400}}}"#;
    let e = MachineDef::from_slice(body).unwrap_err().to_string();
    assert!(e.contains("axes.X.kv"), "{e}");
    let e = MachineDef::from_slice(br#"{"kinematics": "xyz"} trailing"#).unwrap_err();
    assert!(e.to_string().contains("trailing"), "{e}");
}

/// PUT refuses every machine definition that a simulation would refuse: whatever parses,
/// builds its machine for a contour and its servo axes for a gap diagnosis.
#[test]
fn every_accepted_definition_simulates() {
    for def in accepted() {
        let parsed = MachineDef::from_value(&def).unwrap_or_else(|e| panic!("{def}: {e}"));
        let m = machine_for_simulation("m", &parsed).unwrap_or_else(|e| panic!("{def}: {e}"));
        assert_eq!(m, Machine::from_json(&def).unwrap());
        let s = servo_axes("m", &parsed).unwrap_or_else(|e| panic!("{def}: {e}"));
        assert_eq!(s.names, ["X", "Y", "Z"]);
        for (k, servo) in s.servo.iter().enumerate() {
            assert_eq!(servo, &m.axes[k].servo);
        }
    }
}

#[test]
fn a_partial_machine_gives_the_axes_it_has() {
    let def = MachineDef::from_value(&json!({"kinematics": "xyz",
        "axes": {"X": {"kv": 30, "kp_v": 400}, "Y": {"kv": 30}}}))
    .unwrap();
    let s = servo_axes("m", &def).unwrap();
    assert_eq!(s.names, ["X", "Y"]);
    assert_eq!(s.servo[0].kp_v, Some(400.0));
    let e = machine_for_simulation("m", &def).unwrap_err().to_string();
    assert!(
        e.contains("axis Z") && e.contains("PUT /v1/machines/m"),
        "{e}"
    );
    let bare = MachineDef::from_value(&json!({"kinematics": "xyz"})).unwrap();
    assert!(servo_axes("bare", &bare).unwrap().names.is_empty());
}

#[test]
fn bounds_say_the_range() {
    let e = KV.check("axes.X.kv", -1.0).unwrap_err().to_string();
    assert!(
        e.contains("> 0") && e.contains("10000") && e.contains("1/s"),
        "{e}"
    );
    let e = KFF.check("axes.X.kff", 2.0).unwrap_err().to_string();
    assert!(e.contains("0..1"), "{e}");
    assert_eq!(KFF.check("kff", 0.0).unwrap(), 0.0);
    assert!(KV.check("kv", 0.0).is_err());
    assert!(KV.check("kv", f64::NAN).is_err());
    assert!(KV.check("kv", f64::INFINITY).is_err());
}
