//! Unit tests of `crate::motion::machine`.

use super::*;
use serde_json::json;

#[test]
fn parses_contract_body_with_defaults() {
    let m = Machine::from_json(&json!({
        "kinematics": "xyz",
        "axes": {"X": {"kv": 30}, "Y": {"kv": 30, "kff": 0.5}, "Z": {"kv": 25, "max_accel": 2000}}
    }))
    .unwrap();
    assert_eq!(m.axes.len(), 3);
    assert_eq!(m.axes[1].servo.kff, 0.5);
    assert_eq!(m.axes[2].limits.max_accel, 2000.0);
    assert_eq!(m.axes[0].limits, AxisLimits::LINEAR_DEFAULT);
}

#[test]
fn rejects_missing_axis_and_bad_values_with_names() {
    let e =
        Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": {"kv": 30}}})).unwrap_err();
    assert!(e.to_string().contains("axis Y"), "{e}");
    let e = Machine::from_json(&json!({"kinematics": "xyz",
            "axes": {"X": {"kv": 30}, "Y": {"kv": 30}, "Z": {"kv": 30, "max_jerk": -1}}}))
    .unwrap_err();
    assert!(e.to_string().contains("axes.Z.max_jerk"), "{e}");
    let e = Machine::from_json(&json!({"kinematics": "xyz",
            "axes": {"X": {"kv": 30}, "Y": {"kv": 30}, "Z": {"kv": 30}, "A": {"kv": 30}}}))
    .unwrap_err();
    assert!(e.to_string().contains("axis 'A'"), "{e}");
}

#[test]
fn physical_parameters_fill_kp_v_and_tc() {
    let m = Machine::from_json(&json!({
            "kinematics": "xyzac_table",
            "geometry": {"a_axis_origin": [0, 0, -100], "tool_length": 80},
            "axes": {
                "X": {"kv": 30, "physical": {"motor_inertia_kg_m2": 0.001, "velocity_gain_nm_s_per_rad": 0.5,
                      "current_bandwidth_hz": 1000, "lead_mm": 10, "table_mass_kg": 200,
                      "axial_stiffness_n_per_um": 150}},
                "Y": {"kv": 30}, "Z": {"kv": 30}, "A": {"kv": 20},
                "C": {"kv": 20, "physical": {"motor_inertia_kg_m2": 0.002, "velocity_gain_nm_s_per_rad": 1.0,
                      "gear_ratio": 90, "table_inertia_kg_m2": 2.0}}
            }
        }))
        .unwrap();
    let jx = 0.001 + 200.0 * (0.01 / std::f64::consts::TAU).powi(2);
    assert!((m.axes[0].servo.kp_v.unwrap() - 0.5 / jx).abs() < 1e-9);
    assert!(m.axes[0].structure.is_some());
    let jc = 0.002 + 2.0 / 8100.0;
    assert!((m.axes[4].servo.kp_v.unwrap() - 1.0 / jc).abs() < 1e-9);
    assert!(m.axes[4].structure.is_none());
}
