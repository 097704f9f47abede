//! A stored machine definition (JSON, as `PUT /v1/machines/{id}` keeps it) read for a
//! simulation: the whole machine ([`machine_for_simulation`]) or just the servo axes X, Y(, Z)
//! a motion-gap diagnosis needs ([`servo_axes`]); and the interpolation periods a simulation
//! answers ([`check_period`]). Errors name the machine and the PUT that fixes it.

use serde_json::Value;

use super::error::Error;
use super::machine::Machine;
use super::physical::StructuralMode;
use super::servo::ServoAxis;

/// Accepts an interpolation period `period_s` (s) of a contour simulation: finite, 1e-5..0.1.
pub fn check_period(period_s: f64) -> Result<(), Error> {
    if period_s.is_finite() && (1e-5..=0.1).contains(&period_s) {
        Ok(())
    } else {
        Err(Error::PeriodOutOfRange(period_s))
    }
}

/// Parses a stored machine definition for simulation ([`Error::NotSimulable`] naming the fix).
pub fn machine_for_simulation(id: &str, def: &Value) -> Result<Machine, Error> {
    Machine::from_json(def).map_err(|e| Error::NotSimulable {
        machine: id.to_string(),
        reason: e.to_string(),
    })
}

/// The servo models a motion simulation of a machine uses, per axis in the order X, Y, Z.
#[derive(Clone, Debug, Default)]
pub struct ServoAxes {
    /// Machine id (for messages).
    pub machine: String,
    /// Axis letters.
    pub names: Vec<String>,
    /// CONTRACT cascade per axis.
    pub servo: Vec<ServoAxis>,
    /// Structural mode per axis (from the definition's "physical" parameters), if any.
    pub structure: Vec<Option<StructuralMode>>,
}

/// The X, Y(, Z) servo models of a stored machine definition: the machine model when the
/// whole definition simulates (physical parameters mapped onto the cascade, structural modes),
/// otherwise the CONTRACT cascade of just the axes present, so a 2-axis diagnosis needs only
/// X and Y. [`Error::NotAServo`] or [`Error::AxisServo`] when an axis' servo is invalid.
pub fn servo_axes(id: &str, def: &Value) -> Result<ServoAxes, Error> {
    let mut out = ServoAxes {
        machine: id.to_string(),
        ..ServoAxes::default()
    };
    if let Ok(m) = Machine::from_json(def) {
        for name in ["X", "Y", "Z"] {
            let Some(a) = m.axes.iter().find(|a| a.name == name) else {
                break;
            };
            out.names.push(name.to_string());
            out.servo.push(a.servo.clone());
            out.structure.push(a.structure);
        }
        if !out.names.is_empty() {
            return Ok(out);
        }
    }
    for name in ["X", "Y", "Z"] {
        let Some(v) = def.get("axes").and_then(|a| a.get(name)) else {
            break;
        };
        let servo: ServoAxis = serde_json::from_value(v.clone()).map_err(|e| Error::NotAServo {
            machine: id.to_string(),
            axis: name,
            reason: e.to_string(),
        })?;
        servo.validate().map_err(|e| Error::AxisServo {
            machine: id.to_string(),
            axis: name,
            source: Box::new(e),
        })?;
        out.names.push(name.to_string());
        out.servo.push(servo);
        out.structure.push(None);
    }
    Ok(out)
}
