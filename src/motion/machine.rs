//! A machine as the motion core sees it, parsed from the stored machine JSON.
//!
//! CONTRACT body `{"kinematics": "xyz" | "xyzac_table", "axes": {AXIS: SERVO}}` plus these
//! optional extension fields (units in the names or stated):
//! - per axis, beside the servo keys: `"max_vel"` (mm/s or deg/s), `"max_accel"` (mm/s² or
//!   deg/s²), `"max_jerk"` (mm/s³ or deg/s³), and `"physical"` ([`PhysicalAxis`]);
//! - top level: `"geometry"` ([`TableGeometry`], xyzac_table only) and `"rapid_mm_min"`.
//!
//! Unknown keys are left alone (other capabilities store their own parameters there).

use serde_json::Value;

use super::error::Error;
use super::kinematics::{Kinematics, TableGeometry};
use super::physical::{PhysicalAxis, StructuralMode};
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
    pub limits: AxisLimits,
    /// Table compliance after the cascade (from `physical`), if a stiffness is given.
    pub structure: Option<StructuralMode>,
}

/// A machine: kinematics, axes in the order X, Y, Z[, A, C], rapid rate.
#[derive(Clone, Debug, PartialEq)]
pub struct Machine {
    pub kinematics: Kinematics,
    pub axes: Vec<MachineAxis>,
    /// G0 rate along the path, mm/min (each axis still capped by its `max_vel`).
    pub rapid_mm_min: f64,
}

const AXIS_NAMES: [&str; 5] = ["X", "Y", "Z", "A", "C"];

fn positive(field: String, v: &Value) -> Result<f64, Error> {
    match v.as_f64() {
        Some(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(Error::InvalidMachine(format!(
            "{field} must be a positive number, got {v}"
        ))),
    }
}

impl Machine {
    /// Parses and validates the stored machine definition (see module docs).
    /// Every axis of the kinematics needs a servo (`kv` at least): a contour prediction
    /// without one would silently assume a perfect axis.
    pub fn from_json(def: &Value) -> Result<Machine, Error> {
        let obj = def
            .as_object()
            .ok_or_else(|| Error::InvalidMachine("the definition must be a JSON object".into()))?;
        let kin_name = obj
            .get("kinematics")
            .and_then(Value::as_str)
            .unwrap_or("xyz");
        let geometry = match obj.get("geometry") {
            None | Some(Value::Null) => None,
            Some(g) => Some(
                serde_json::from_value::<TableGeometry>(g.clone())
                    .map_err(|e| Error::InvalidMachine(format!("geometry: {e}")))?,
            ),
        };
        let kinematics = match kin_name {
            "xyz" => {
                if geometry.is_some() {
                    return Err(Error::InvalidMachine(
                        "geometry (table offsets, tool length) applies only to kinematics xyzac_table".into(),
                    ));
                }
                Kinematics::Xyz
            }
            "xyzac_table" => {
                let g = geometry.unwrap_or_default();
                let finite = g
                    .a_axis_origin
                    .iter()
                    .chain(g.c_axis_origin.iter())
                    .all(|v| v.is_finite())
                    && g.tool_length.is_finite();
                if !finite {
                    return Err(Error::InvalidMachine(
                        "geometry values must be finite".into(),
                    ));
                }
                Kinematics::XyzacTable(g)
            }
            other => {
                return Err(Error::InvalidMachine(format!(
                    "kinematics '{other}' is not supported: use \"xyz\" or \"xyzac_table\""
                )));
            }
        };
        let rapid_mm_min = match obj.get("rapid_mm_min") {
            None | Some(Value::Null) => 30_000.0,
            Some(v) => positive("rapid_mm_min".into(), v)?,
        };
        let empty = serde_json::Map::new();
        let axes_obj = match obj.get("axes") {
            None | Some(Value::Null) => &empty,
            Some(Value::Object(m)) => m,
            Some(_) => {
                return Err(Error::InvalidMachine(
                    "axes must be an object {AXIS: SERVO}".into(),
                ));
            }
        };
        let n = kinematics.axis_count();
        for key in axes_obj.keys() {
            if !AXIS_NAMES[..n].contains(&key.as_str()) {
                return Err(Error::InvalidMachine(format!(
                    "axis '{key}' does not exist on a {kin_name} machine (axes: {})",
                    AXIS_NAMES[..n].join(", ")
                )));
            }
        }
        let mut axes = Vec::with_capacity(n);
        for (i, name) in AXIS_NAMES[..n].iter().enumerate() {
            let rotary = i >= 3;
            let a = axes_obj.get(*name).ok_or_else(|| {
                Error::InvalidMachine(format!(
                    "axis {name} has no servo model: PUT the machine with axes.{name} = {{\"kv\": ...}}"
                ))
            })?;
            axes.push(parse_axis(name, a, rotary)?);
        }
        Ok(Machine {
            kinematics,
            axes,
            rapid_mm_min,
        })
    }
}

fn parse_axis(name: &'static str, a: &Value, rotary: bool) -> Result<MachineAxis, Error> {
    let mut servo: ServoAxis = serde_json::from_value(a.clone())
        .map_err(|e| Error::InvalidMachine(format!("axes.{name}: {e}")))?;
    let mut limits = if rotary {
        AxisLimits::ROTARY_DEFAULT
    } else {
        AxisLimits::LINEAR_DEFAULT
    };
    for (key, slot) in [
        ("max_vel", &mut limits.max_vel),
        ("max_accel", &mut limits.max_accel),
        ("max_jerk", &mut limits.max_jerk),
    ] {
        if let Some(v) = a.get(key).filter(|v| !v.is_null()) {
            *slot = positive(format!("axes.{name}.{key}"), v)?;
        }
    }
    let mut structure = None;
    if let Some(p) = a.get("physical").filter(|v| !v.is_null()) {
        let phys: PhysicalAxis = serde_json::from_value(p.clone())
            .map_err(|e| Error::InvalidMachine(format!("axes.{name}.physical: {e}")))?;
        let named = |e: Error| Error::InvalidMachine(format!("axes.{name}: {e}"));
        if servo.kp_v.is_none() {
            servo.kp_v = phys.kp_v(rotary).map_err(named)?;
        }
        if servo.tc.is_none() {
            servo.tc = phys.tc().map_err(named)?;
        }
        structure = phys.structural_mode(rotary).map_err(named)?;
    }
    servo
        .validate()
        .map_err(|e| Error::InvalidMachine(format!("axes.{name}: {e}")))?;
    Ok(MachineAxis {
        name,
        servo,
        limits,
        structure,
    })
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
