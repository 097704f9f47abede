//! A machine as the motion core simulates it, built from a checked [`MachineDef`] (the stored
//! machine JSON; its keys, extensions and ranges are documented there).

use serde_json::Value;

use super::controller::ControllerLimits;
use super::def::{KinematicsKind, MachineDef};
use super::effects::{AxisModel, Effects};
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
    /// The controller's limits on dense blocks (default: none, the service's own planning).
    pub controller: ControllerLimits,
    /// Effects stored with the machine, added to every simulation (default: none).
    pub effects: Effects,
}

impl Machine {
    /// The axes as the stored effects see them ([`AxisModel`]).
    pub fn axis_models(&self) -> Vec<AxisModel<'_>> {
        self.axes
            .iter()
            .map(|a| AxisModel {
                name: a.name,
                servo: &a.servo,
                structure: a.structure,
            })
            .collect()
    }

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
            controller: match &def.controller {
                Some(c) => c.limits()?,
                None => ControllerLimits::default(),
            },
            effects: Effects::default(),
        })
    }
}

#[cfg(test)]
mod tests;
