//! A machine as the motion core simulates it, built from a checked [`MachineDef`] (the stored
//! machine JSON; its keys, extensions and ranges are documented there).

use serde_json::Value;

use super::def::{KinematicsKind, MachineDef};
use super::error::Error;
use super::kinematics::Kinematics;
use super::physical::StructuralMode;
use super::servo::ServoAxis;

/// Velocity, acceleration and jerk caps of one axis used by the interpolator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLimits {
    /// mm/s (linear) or deg/s (rotary).
    pub max_vel: f64,
    /// mm/s² or deg/s².
    pub max_accel: f64,
    /// mm/s³ or deg/s³.
    pub max_jerk: f64,
}

impl AxisLimits {
    /// Defaults of a mid-size machining centre: 500 mm/s (30 m/min), 5 m/s², 100 m/s³.
    pub const LINEAR_DEFAULT: AxisLimits = AxisLimits {
        max_vel: 500.0,
        max_accel: 5000.0,
        max_jerk: 100_000.0,
    };
    /// Defaults of a tilting rotary table: 180 deg/s (30 rpm), 1800 deg/s², 36000 deg/s³.
    pub const ROTARY_DEFAULT: AxisLimits = AxisLimits {
        max_vel: 180.0,
        max_accel: 1800.0,
        max_jerk: 36_000.0,
    };
}

/// One machine axis: its servo cascade, limits and optional structural mode.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineAxis {
    /// "X", "Y", "Z", "A" or "C".
    pub name: &'static str,
    /// The normalized cascade, with `kp_v`/`tc` filled from `physical` when absent.
    pub servo: ServoAxis,
    /// Velocity, acceleration and jerk caps the interpolator plans with (mm/s, mm/s², mm/s³
    /// or deg/s, deg/s², deg/s³).
    pub limits: AxisLimits,
    /// Table compliance after the cascade (from `physical`), if a stiffness is given.
    pub structure: Option<StructuralMode>,
}

/// A machine: kinematics, axes in the order X, Y, Z[, A, C], rapid rate.
#[derive(Clone, Debug, PartialEq)]
pub struct Machine {
    /// The kinematic chain (`xyz`, or `xyzac_table` with its table geometry).
    pub kinematics: Kinematics,
    /// The axes in the order X, Y, Z[, A, C], one per column of a trajectory.
    pub axes: Vec<MachineAxis>,
    /// G0 rate along the path, mm/min (each axis still capped by its `max_vel`).
    pub rapid_mm_min: f64,
}

impl Machine {
    /// Parses, validates ([`MachineDef::from_value`]) and builds a machine from its JSON.
    pub fn from_json(def: &Value) -> Result<Machine, Error> {
        Machine::from_def(&MachineDef::from_value(def)?)
    }

    /// Builds the simulated machine from a definition that passed [`MachineDef::validate`].
    /// Every axis of the kinematics needs a servo (`kv` at least): a contour prediction
    /// without one would silently assume a perfect axis.
    pub fn from_def(def: &MachineDef) -> Result<Machine, Error> {
        let kinematics = match def.kinematics {
            KinematicsKind::Xyz => Kinematics::Xyz,
            KinematicsKind::XyzacTable => {
                Kinematics::XyzacTable(def.geometry.clone().unwrap_or_default())
            }
        };
        let mut axes = Vec::new();
        for (i, name) in def.kinematics.axis_names().iter().enumerate() {
            let a = def.axes.as_ref().and_then(|a| a.get(name)).ok_or_else(|| {
                Error::InvalidMachine(format!(
                    "axis {name} has no servo model: PUT the machine with axes.{name} = {{\"kv\": ...}}"
                ))
            })?;
            axes.push(a.build(name, i >= 3)?);
        }
        Ok(Machine {
            kinematics,
            axes,
            rapid_mm_min: def.rapid_mm_min.unwrap_or(30_000.0),
        })
    }
}

#[cfg(test)]
mod tests {
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
        let e = Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": {"kv": 30}}}))
            .unwrap_err();
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
}
