//! Effects stored with a machine (backlash, friction, gain mismatch, scale, ...; fitted by the
//! gap diagnosis and adopted with `PUT /v1/machines/{m}/effects`) added to its simulation.
//!
//! The motion core only knows the hook: [`AddedEffects`] turns the linear simulation of a
//! command into the simulation with the effects. The formulas live with the diagnosis that fits
//! them (`crate::gap::adopted`), so a simulation and a diagnosis add an effect the same way.

use std::fmt;
use std::sync::Arc;

use super::error::Error;
use super::physical::StructuralMode;
use super::servo::ServoAxis;

/// One simulated axis, as an effect needs it: its letter, servo cascade and structural mode.
#[derive(Clone, Copy, Debug)]
pub struct AxisModel<'a> {
    /// Axis letter ("X", "Y", "Z", "A" or "C").
    pub name: &'a str,
    /// The stored cascade (openapi.yaml schema `Servo`).
    pub servo: &'a ServoAxis,
    /// The structural mode after the cascade, if any.
    pub structure: Option<StructuralMode>,
}

/// Unmodelled effects added to a machine's linear simulation.
pub trait AddedEffects: Send + Sync {
    /// Positions with the effects (mm or degrees, one column per axis of `axes`) of the command
    /// `commanded` sampled every `period_s` s, given its linear simulation `linear` (same
    /// shape). An effect on an axis that is not in `axes` is not applied.
    fn apply(
        &self,
        axes: &[AxisModel<'_>],
        period_s: f64,
        commanded: &[Vec<f64>],
        linear: &[Vec<f64>],
    ) -> Result<Vec<Vec<f64>>, Error>;

    /// The stored version these effects are (`effects_version` of the answers).
    fn version(&self) -> i64;
}

/// The effects a simulation adds: none (the default) or a stored set.
#[derive(Clone, Default)]
pub struct Effects(pub Option<Arc<dyn AddedEffects>>);

impl Effects {
    /// The stored version used, `None` when no effects are added.
    pub fn version(&self) -> Option<i64> {
        self.0.as_ref().map(|e| e.version())
    }

    /// `linear` with the effects added (see [`AddedEffects::apply`]); `linear` itself when
    /// there are none.
    pub fn apply(
        &self,
        axes: &[AxisModel<'_>],
        period_s: f64,
        commanded: &[Vec<f64>],
        linear: Vec<Vec<f64>>,
    ) -> Result<Vec<Vec<f64>>, Error> {
        match &self.0 {
            None => Ok(linear),
            Some(e) => e.apply(axes, period_s, commanded, &linear),
        }
    }
}

impl fmt::Debug for Effects {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.version() {
            Some(v) => write!(f, "Effects(version {v})"),
            None => write!(f, "Effects(none)"),
        }
    }
}

impl PartialEq for Effects {
    fn eq(&self, other: &Self) -> bool {
        match (&self.0, &other.0) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}
