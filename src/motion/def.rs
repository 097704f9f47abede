//! The machine definition as PUT stores it, parsed once into a checked type: [`MachineDef`].
//!
//! Body of `PUT /v1/machines/{id}` (HTTP contract "Machines", "Servo model"; openapi.yaml schemas `Machine`, `Servo`):
//! `{"name"?: str, "kinematics": "xyz" | "xyzac_table", "axes"?: {AXIS: SERVO},
//! "geometry"?: {...}, "rapid_mm_min"?: mm/min}`, where SERVO is the normalized cascade
//! `{"kv", "kff"?, "kp_v"?, "ti_v"?, "tc"?}` plus the extensions `"max_vel"`, `"max_accel"`,
//! `"max_jerk"` (interpolator limits) and `"physical"` ([`PhysicalAxis`]), and the optional
//! `"controller"` ([`ControllerDef`]: the controller's limits on dense blocks).
//!
//! Why one type: the service used to check a definition three times with three rule sets (at
//! PUT, for a contour, for a gap diagnosis), so PUT stored what a simulation later refused.
//! Now every rule a simulation applies lives in [`MachineDef::validate`], which the parsers
//! run, and every simulation builds its [`Machine`](super::Machine) from a `MachineDef` (HTTP contract
//! v1.1 "Definitions are validated when stored, not when used"). Unknown keys are refused by
//! serde with the key and the keys allowed; the JSON path of any refusal comes from
//! `serde_path_to_error`. The one thing a simulation may still refuse is an axis that is
//! absent: `axes` is optional in the HTTP contract (a machine may carry only surfaces or a
//! volumetric map), and a contour needs every axis of its kinematics.

use serde::{Deserialize, Serialize};
use serde_json::Value;

pub use super::bounds::{
    Bounds, GEOMETRY_MM, KFF, KP_V, KV, MAX_ACCEL, MAX_JERK, MAX_VEL, PHYSICAL, RAPID_MM_MIN, TC,
    TI_V,
};

use super::controller::ControllerDef;
use super::error::Error;
use super::kinematics::TableGeometry;
use super::machine::{AxisLimits, MachineAxis};
use super::physical::PhysicalAxis;
use super::servo::ServoAxis;

/// Kinematic chains the service knows (the machine JSON's `"kinematics"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum KinematicsKind {
    /// Three linear axes X, Y, Z.
    #[serde(rename = "xyz")]
    Xyz,
    /// X, Y, Z plus a tilting (A) and rotary (C) table.
    #[serde(rename = "xyzac_table")]
    XyzacTable,
}

impl KinematicsKind {
    /// The name as the JSON spells it.
    pub fn name(self) -> &'static str {
        match self {
            KinematicsKind::Xyz => "xyz",
            KinematicsKind::XyzacTable => "xyzac_table",
        }
    }

    /// The axes of this kinematics, in the machine's axis order.
    pub fn axis_names(self) -> &'static [&'static str] {
        match self {
            KinematicsKind::Xyz => &["X", "Y", "Z"],
            KinematicsKind::XyzacTable => &["X", "Y", "Z", "A", "C"],
        }
    }
}

/// A machine definition (see the module docs); build one with [`MachineDef::from_slice`] or
/// [`MachineDef::from_value`], which both run [`MachineDef::validate`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a machine definition object {\"kinematics\": \"xyz\" | \"xyzac_table\", \"axes\"?: {AXIS: SERVO}}"
)]
pub struct MachineDef {
    /// Display name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Kinematic chain.
    pub kinematics: KinematicsKind,
    /// Servo model per axis; axes may be absent (then the machine does not simulate).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes: Option<AxesDef>,
    /// Table offsets and tool length (xyzac_table only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geometry: Option<TableGeometry>,
    /// G0 rate along the path, mm/min (default 30,000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rapid_mm_min: Option<f64>,
    /// Machine home (G28, and G53 is modelled once it is known), [x, y, z] mm in machine
    /// coordinates; a request's `home` overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home: Option<[f64; 3]>,
    /// G30 position (second reference point), [x, y, z] mm in machine coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g30: Option<[f64; 3]>,
    /// The controller's limits on dense blocks (segment cap, block rate, look-ahead depth);
    /// absent: the service's own planning.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<ControllerDef>,
}

/// The `"axes"` object: one optional servo per axis letter.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "an object mapping an axis letter (X, Y, Z, A, C) to its servo model"
)]
pub struct AxesDef {
    /// Axis X.
    #[serde(rename = "X", default, skip_serializing_if = "Option::is_none")]
    pub x: Option<AxisDef>,
    /// Axis Y.
    #[serde(rename = "Y", default, skip_serializing_if = "Option::is_none")]
    pub y: Option<AxisDef>,
    /// Axis Z.
    #[serde(rename = "Z", default, skip_serializing_if = "Option::is_none")]
    pub z: Option<AxisDef>,
    /// Axis A (table tilt about X).
    #[serde(rename = "A", default, skip_serializing_if = "Option::is_none")]
    pub a: Option<AxisDef>,
    /// Axis C (table rotation about Z).
    #[serde(rename = "C", default, skip_serializing_if = "Option::is_none")]
    pub c: Option<AxisDef>,
}

impl AxesDef {
    /// The servo of axis `name` ("X", "Y", "Z", "A" or "C"), if given.
    pub fn get(&self, name: &str) -> Option<&AxisDef> {
        match name {
            "X" => self.x.as_ref(),
            "Y" => self.y.as_ref(),
            "Z" => self.z.as_ref(),
            "A" => self.a.as_ref(),
            "C" => self.c.as_ref(),
            _ => None,
        }
    }

    /// The axes given, as (letter, servo), in the order X, Y, Z, A, C.
    pub fn present(&self) -> impl Iterator<Item = (&'static str, &AxisDef)> {
        ["X", "Y", "Z", "A", "C"]
            .into_iter()
            .filter_map(|n| self.get(n).map(|a| (n, a)))
    }
}

/// One axis: the servo cascade of openapi.yaml schema `Servo` (units: 1/s for gains, s for times), limits, physical drive.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a servo model object like {\"kv\": 30.0} (kv in 1/s)"
)]
pub struct AxisDef {
    /// Position-loop gain, 1/s ([`KV`]).
    pub kv: f64,
    /// Velocity feed-forward fraction ([`KFF`], default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kff: Option<f64>,
    /// Velocity-loop gain, 1/s ([`KP_V`]); absent: ideal velocity loop (or from `physical`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kp_v: Option<f64>,
    /// Velocity-loop integral time, s ([`TI_V`]); absent: no integral action.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ti_v: Option<f64>,
    /// Current-loop time constant, s ([`TC`]); absent: ideal current loop (or from `physical`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tc: Option<f64>,
    /// Velocity cap, mm/s or deg/s ([`MAX_VEL`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_vel: Option<f64>,
    /// Acceleration cap, mm/s² or deg/s² ([`MAX_ACCEL`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_accel: Option<f64>,
    /// Jerk cap, mm/s³ or deg/s³ ([`MAX_JERK`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_jerk: Option<f64>,
    /// Physical drive parameters ([`PHYSICAL`] ranges).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub physical: Option<PhysicalAxis>,
}

fn path_error<E: std::fmt::Display>(e: serde_path_to_error::Error<E>) -> Error {
    let path = e.path().to_string();
    Error::BadDefinition {
        field: if path == "." {
            "the definition".into()
        } else {
            path
        },
        message: e.inner().to_string(),
    }
}

/// Serde's derived structs also read JSON arrays (`[30]` as `{"kv": 30}`); a definition is
/// objects all the way down, so anything else is refused by name first.
fn check_objects(value: &Value) -> Result<(), Error> {
    fn object<'a>(field: &str, v: &'a Value, like: &str) -> Result<Option<&'a Value>, Error> {
        match v {
            Value::Null => Ok(None),
            Value::Object(_) => Ok(Some(v)),
            other => Err(Error::BadDefinition {
                field: field.to_string(),
                message: format!("must be a JSON object like {like}, got {other}"),
            }),
        }
    }
    let like_def = "{\"kinematics\": \"xyz\", \"axes\": {\"X\": {\"kv\": 30}}}";
    if !value.is_object() {
        return Err(Error::BadDefinition {
            field: "the definition".into(),
            message: format!("must be a JSON object like {like_def}, got {value}"),
        });
    }
    let top = value;
    if let Some(g) = top.get("geometry") {
        object(
            "geometry",
            g,
            "{\"a_axis_origin\": [x, y, z], \"tool_length\": mm}",
        )?;
    }
    if let Some(c) = top.get("controller") {
        object(
            "controller",
            c,
            "{\"kind\": \"linuxcnc\"} or {\"kind\": \"grbl\", \"lookahead_blocks\": 15}",
        )?;
    }
    let Some(Some(axes)) = top
        .get("axes")
        .map(|a| object("axes", a, "{\"X\": {\"kv\": 30}}"))
        .transpose()?
    else {
        return Ok(());
    };
    for (name, axis) in axes.as_object().into_iter().flatten() {
        let field = format!("axes.{name}");
        if let Some(axis) = object(&field, axis, "{\"kv\": 30}")?
            && let Some(p) = axis.get("physical")
        {
            object(
                &format!("{field}.physical"),
                p,
                "{\"motor_inertia_kg_m2\": 0.001, ...}",
            )?;
        }
    }
    Ok(())
}

impl MachineDef {
    /// Parses and validates a definition from JSON bytes (a PUT body). A number JSON cannot
    /// hold (`1e400`) is named by its path like any other refusal.
    pub fn from_slice(bytes: &[u8]) -> Result<MachineDef, Error> {
        match serde_json::from_slice::<Value>(bytes) {
            Ok(value) => MachineDef::from_value(&value),
            Err(syntax) => {
                // Only the typed parse knows where in the tree the bad token sits.
                let mut de = serde_json::Deserializer::from_slice(bytes);
                let typed: Result<MachineDef, _> = serde_path_to_error::deserialize(&mut de);
                Err(match typed {
                    Err(e) => path_error(e),
                    Ok(_) => Error::BadDefinition {
                        field: "the definition".into(),
                        message: syntax.to_string(),
                    },
                })
            }
        }
    }

    /// Parses and validates a definition from JSON (a stored definition, a CLI file).
    pub fn from_value(value: &Value) -> Result<MachineDef, Error> {
        check_objects(value)?;
        let def: MachineDef = serde_path_to_error::deserialize(value).map_err(path_error)?;
        def.validate()?;
        Ok(def)
    }

    /// Every rule any simulation applies, so a definition that passes never fails later for a
    /// reason it could have shown: axes belong to the kinematics; geometry only on
    /// `xyzac_table` and finite (|v| ≤ [`GEOMETRY_MM`]); `rapid_mm_min` in [`RAPID_MM_MIN`];
    /// per axis the ranges [`KV`], [`KFF`], [`KP_V`], [`TI_V`], [`TC`], [`MAX_VEL`],
    /// [`MAX_ACCEL`], [`MAX_JERK`], [`PHYSICAL`], the physical parameters each axis kind needs,
    /// and a stable closed loop after `physical` fills `kp_v`/`tc` ([`ServoAxis::validate`]);
    /// the controller's limits ([`ControllerDef::limits`]).
    pub fn validate(&self) -> Result<(), Error> {
        let kin = self.kinematics;
        if let Some(g) = &self.geometry {
            if kin != KinematicsKind::XyzacTable {
                return Err(Error::BadDefinition {
                    field: "geometry".into(),
                    message:
                        "table offsets and tool length apply only to kinematics \"xyzac_table\""
                            .into(),
                });
            }
            let fields = [
                ("a_axis_origin", &g.a_axis_origin[..]),
                ("c_axis_origin", &g.c_axis_origin[..]),
                ("tool_length", std::slice::from_ref(&g.tool_length)),
            ];
            for (name, values) in fields {
                if let Some(v) = values
                    .iter()
                    .find(|v| !(v.is_finite() && v.abs() <= GEOMETRY_MM))
                {
                    return Err(Error::BadDefinition {
                        field: format!("geometry.{name}"),
                        message: format!(
                            "every value must be a finite number of mm, at most {GEOMETRY_MM} in size, got {v}"
                        ),
                    });
                }
            }
        }
        if let Some(r) = self.rapid_mm_min {
            RAPID_MM_MIN.check("rapid_mm_min", r)?;
        }
        if let Some(c) = &self.controller {
            c.limits()?;
        }
        for (name, point) in [("home", self.home), ("g30", self.g30)] {
            if let Some(v) = point
                .iter()
                .flatten()
                .find(|v| !(v.is_finite() && v.abs() <= GEOMETRY_MM))
            {
                return Err(Error::BadDefinition {
                    field: name.into(),
                    message: format!(
                        "[x, y, z] must be finite mm in machine coordinates, at most \
                         {GEOMETRY_MM} in size, got {v}"
                    ),
                });
            }
        }
        if let Some(axes) = &self.axes {
            let allowed = kin.axis_names();
            for (name, axis) in axes.present() {
                let Some(i) = allowed.iter().position(|a| *a == name) else {
                    return Err(Error::BadDefinition {
                        field: format!("axes.{name}"),
                        message: format!(
                            "axis '{name}' does not exist on kinematics '{}' (axes: {})",
                            kin.name(),
                            allowed.join(", ")
                        ),
                    });
                };
                axis.build(name, i >= 3)?;
            }
        }
        Ok(())
    }
}

impl AxisDef {
    /// The simulated axis: ranges checked, `kp_v`/`tc` filled from `physical` when absent,
    /// structural mode from `physical`, stability checked. Errors name `axes.{name}.{field}`.
    pub fn build(&self, name: &'static str, rotary: bool) -> Result<MachineAxis, Error> {
        let field = |key: &str| format!("axes.{name}.{key}");
        let mut servo = ServoAxis {
            kv: KV.check(&field("kv"), self.kv)?,
            kff: match self.kff {
                Some(k) => KFF.check(&field("kff"), k)?,
                None => 0.0,
            },
            kp_v: self
                .kp_v
                .map(|v| KP_V.check(&field("kp_v"), v))
                .transpose()?,
            ti_v: self
                .ti_v
                .map(|v| TI_V.check(&field("ti_v"), v))
                .transpose()?,
            tc: self.tc.map(|v| TC.check(&field("tc"), v)).transpose()?,
        };
        let mut limits = if rotary {
            AxisLimits::ROTARY_DEFAULT
        } else {
            AxisLimits::LINEAR_DEFAULT
        };
        for (key, given, bounds, slot) in [
            ("max_vel", self.max_vel, MAX_VEL, &mut limits.max_vel),
            (
                "max_accel",
                self.max_accel,
                MAX_ACCEL,
                &mut limits.max_accel,
            ),
            ("max_jerk", self.max_jerk, MAX_JERK, &mut limits.max_jerk),
        ] {
            if let Some(v) = given {
                *slot = bounds.check(&field(key), v)?;
            }
        }
        let mut structure = None;
        if let Some(phys) = &self.physical {
            check_physical(name, phys)?;
            let named = |e: Error| Error::BadDefinition {
                field: format!("axes.{name}"),
                message: e.to_string(),
            };
            if servo.kp_v.is_none() {
                servo.kp_v = phys
                    .kp_v(rotary)
                    .map_err(named)?
                    .map(|v| KP_V.check(&field("kp_v (from physical)"), v))
                    .transpose()?;
            }
            if servo.tc.is_none() {
                servo.tc = phys
                    .tc()
                    .map_err(named)?
                    .map(|v| TC.check(&field("tc (from physical)"), v))
                    .transpose()?;
            }
            structure = phys.structural_mode(rotary).map_err(named)?;
        }
        servo.validate().map_err(|e| Error::BadDefinition {
            field: format!("axes.{name}"),
            message: e.to_string(),
        })?;
        Ok(MachineAxis {
            name,
            servo,
            limits,
            structure,
        })
    }
}

/// Checks every given physical parameter against [`PHYSICAL`].
fn check_physical(axis: &str, p: &PhysicalAxis) -> Result<(), Error> {
    let values = [
        Some(p.motor_inertia_kg_m2),
        p.velocity_gain_nm_s_per_rad,
        p.current_bandwidth_hz,
        p.lead_mm,
        p.table_mass_kg,
        p.axial_stiffness_n_per_um,
        p.screw_torsional_stiffness_nm_per_rad,
        p.table_damping_n_s_per_m,
        p.gear_ratio,
        p.table_inertia_kg_m2,
        p.torsional_stiffness_nm_per_rad,
        p.table_damping_nm_s_per_rad,
    ];
    for ((key, bounds), v) in PHYSICAL.iter().zip(values) {
        if let Some(v) = v {
            bounds.check(&format!("axes.{axis}.physical.{key}"), v)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
