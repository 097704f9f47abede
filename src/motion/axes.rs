//! A checked machine definition ([`MachineDef`]) read for a simulation: the whole machine
//! ([`machine_for_simulation`]) or just the servo axes X, Y(, Z) a motion-gap diagnosis needs
//! ([`servo_axes`]); and the interpolation periods a simulation answers ([`check_period`]).
//! Errors name the machine and the PUT that fixes it.

use serde_json::Value;

use super::def::MachineDef;
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

/// Parses a stored machine definition ([`MachineDef::from_value`]). A definition stored before
/// the service validated everything at PUT may fail: [`Error::NotSimulable`] names the fix.
pub fn stored_definition(id: &str, def: &Value) -> Result<MachineDef, Error> {
    MachineDef::from_value(def).map_err(|e| not_simulable(id, e))
}

fn not_simulable(id: &str, e: Error) -> Error {
    Error::NotSimulable {
        machine: id.to_string(),
        reason: e.to_string(),
    }
}

/// The simulated machine of a checked definition ([`Error::NotSimulable`] naming the fix when
/// an axis of the kinematics has no servo).
pub fn machine_for_simulation(id: &str, def: &MachineDef) -> Result<Machine, Error> {
    Machine::from_def(def).map_err(|e| not_simulable(id, e))
}

/// The servo models a motion simulation of a machine uses, per axis in the order X, Y, Z.
#[derive(Clone, Debug, Default)]
pub struct ServoAxes {
    /// Machine id (for messages).
    pub machine: String,
    /// Axis letters.
    pub names: Vec<String>,
    /// servo cascade (openapi.yaml schema `Servo`) per axis.
    pub servo: Vec<ServoAxis>,
    /// Structural mode per axis (from the definition's "physical" parameters), if any.
    pub structure: Vec<Option<StructuralMode>>,
    /// Effects stored with the machine, added to the simulation (default: none).
    pub effects: super::effects::Effects,
}

/// The X, Y(, Z) servo models of a checked definition, as far as they are given in that order
/// (so a 2-axis diagnosis needs only X and Y): built by the same rule as the whole machine
/// ([`AxisDef::build`](super::def::AxisDef::build): physical parameters mapped onto the cascade,
/// structural modes). Empty when X is absent; the diagnosis then says the machine has no servo.
pub fn servo_axes(id: &str, def: &MachineDef) -> Result<ServoAxes, Error> {
    let mut out = ServoAxes {
        machine: id.to_string(),
        ..ServoAxes::default()
    };
    for name in ["X", "Y", "Z"] {
        let Some(a) = def.axes.as_ref().and_then(|a| a.get(name)) else {
            break;
        };
        let axis = a.build(name, false).map_err(|e| not_simulable(id, e))?;
        out.names.push(name.to_string());
        out.servo.push(axis.servo);
        out.structure.push(axis.structure);
    }
    Ok(out)
}
