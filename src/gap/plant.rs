//! The simulation the gap is measured against, and its nonlinear extensions: the stored servo
//! cascade per axis (exact discretization) plus Coulomb friction inside the velocity loop and a
//! backlash play operator between motor and table.
//!
//! Written here (no crate): friction needs the cascade's own state space; a generic ODE crate
//! would integrate the linear part inexactly.

use crate::gap::Error;
use crate::motion::servo::{ContinuousServo, DiscreteServo, ServoAxis};
use crate::motion::{AxisModel, Effects, StructuralMode};

/// Friction sub-steps per interpolation period (the friction force is held over a sub-step).
pub const FRICTION_SUBSTEPS: usize = 4;

/// One axis of the plant: the stored servo discretized for the period and for sub-steps.
#[derive(Clone, Debug)]
pub struct AxisPlant {
    /// The stored servo parameters.
    pub servo: ServoAxis,
    /// Interpolation period, s.
    pub period_s: f64,
    exact: DiscreteServo,
    sub: DiscreteServo,
    cont: ContinuousServo,
    structure: Option<StructuralMode>,
}

impl AxisPlant {
    /// Discretizes `servo` for `period_s` (and `period_s / FRICTION_SUBSTEPS`).
    pub fn new(axis_name: &str, servo: &ServoAxis, period_s: f64) -> Result<Self, Error> {
        let wrap = |source| Error::Servo {
            axis: axis_name.to_string(),
            source,
        };
        let exact = DiscreteServo::new(servo, period_s).map_err(wrap)?;
        let sub = DiscreteServo::new(servo, period_s / FRICTION_SUBSTEPS as f64).map_err(wrap)?;
        Ok(Self {
            servo: servo.clone(),
            period_s,
            exact,
            sub,
            cont: servo.continuous(),
            structure: None,
        })
    }

    /// Adds the machine's structural mode between motor and table (Zhang & Chen 2025 eq. 10),
    /// applied to every simulated position as in the contour prediction.
    pub fn with_structure(mut self, structure: Option<StructuralMode>) -> Self {
        self.structure = structure;
        self
    }

    fn table(&self, motor: Vec<f64>) -> Vec<f64> {
        match &self.structure {
            Some(mode) => mode.filter(&motor, self.period_s),
            None => motor,
        }
    }

    /// Whether the stored model has a velocity loop (`kp_v` given).
    pub fn has_velocity_loop(&self) -> bool {
        self.cont.v_index.is_some()
    }

    /// Actual positions (mm) of the stored linear cascade for `command` (mm), exact.
    pub fn linear(&self, command: &[f64]) -> Vec<f64> {
        self.table(self.exact.simulate(command))
    }

    /// Actual positions (mm) with the position-loop gain replaced by `kv` (1/s).
    /// Falls back to the stored response when `kv` makes the loop invalid or unstable.
    pub fn with_kv(&self, kv: f64, command: &[f64]) -> Vec<f64> {
        let servo = ServoAxis {
            kv,
            ..self.servo.clone()
        };
        match DiscreteServo::new(&servo, self.period_s) {
            Ok(d) => self.table(d.simulate(command)),
            Err(_) => vec![f64::NAN; command.len()],
        }
    }

    /// Actual positions (mm) with Coulomb friction of magnitude `f` acting inside the velocity
    /// loop: `dv/dt = a − f·sign(v)`, sticking (v = 0) while the drive stays below `f`.
    /// `f` is an acceleration, mm/s² (friction force / moving mass). For a stored first-order
    /// loop (ideal velocity loop) friction becomes a velocity deficit `f` in mm/s:
    /// `dx/dt = v_ref − f·sign(v_ref)`, zero while `|v_ref| ≤ f`.
    ///
    /// The force is held over sub-steps of period/4 and the linear part is exact, so with
    /// `f = 0` this equals [`AxisPlant::linear`] to rounding. Reference: Armstrong-Hélouvry,
    /// Dupont, Canudas de Wit, "A survey of models ... machines with friction", Automatica 30
    /// (1994), Karnopp stick model. Bad cases: sub-step resolution limits stick timing to
    /// period/4.
    pub fn with_friction(&self, f: f64, command: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(command.len());
        let Some(&c0) = command.first() else {
            return out;
        };
        out.push(c0);
        let h = self.period_s / FRICTION_SUBSTEPS as f64;
        let inv_t = 1.0 / self.period_s;
        match self.cont.v_index {
            Some(vi) => {
                let n = self.cont.a.nrows();
                let row: Vec<f64> = (0..n).map(|j| self.cont.a[(vi, j)]).collect();
                let b_s = self.cont.b_slope[vi];
                let v_eps = 1e-3 * f * h;
                let mut y = [0.0f64; 4];
                for w in command.windows(2) {
                    let s = (w[1] - w[0]) * inv_t;
                    for _ in 0..FRICTION_SUBSTEPS {
                        let v = y[vi];
                        let d = if v.abs() > v_eps {
                            f * v.signum()
                        } else {
                            let drive: f64 =
                                row.iter().zip(&y).map(|(r, yj)| r * yj).sum::<f64>() + b_s * s;
                            if drive.abs() <= f {
                                y[vi] = 0.0;
                                drive
                            } else {
                                f * drive.signum()
                            }
                        };
                        let v_old = y[vi];
                        self.sub.step(&mut y, s, d);
                        // friction alone never reverses the motion: a sign change smaller than
                        // what friction adds in one sub-step is a stop
                        if v_old * y[vi] < 0.0 && y[vi].abs() <= f * h {
                            y[vi] = 0.0;
                        }
                    }
                    out.push(w[1] + y[0]);
                }
            }
            None => {
                let (kv, kff) = (self.servo.kv, self.servo.kff);
                let phi = (-kv * h).exp();
                let g_s = -(1.0 - kff) * (1.0 - phi) / kv;
                let g_d = -(1.0 - phi) / kv;
                let mut e = 0.0;
                for w in command.windows(2) {
                    let s = (w[1] - w[0]) * inv_t;
                    for _ in 0..FRICTION_SUBSTEPS {
                        let v_ref = kff * s - kv * e;
                        let d = if v_ref.abs() > f {
                            f * v_ref.signum()
                        } else {
                            v_ref
                        };
                        e = phi * e + g_s * s + g_d * d;
                    }
                    out.push(w[1] + e);
                }
            }
        }
        self.table(out)
    }
}

/// The stored simulation of a command (mm per axis): each plant's linear response plus the
/// effects stored with the machine, `prior` ([`crate::motion::effects`]). `names` are the
/// plants' axis letters.
pub fn stored_simulation(
    plants: &[AxisPlant],
    names: &[String],
    prior: &Effects,
    cmd: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>, Error> {
    let linear: Vec<Vec<f64>> = plants.iter().zip(cmd).map(|(p, c)| p.linear(c)).collect();
    let models: Vec<AxisModel<'_>> = plants
        .iter()
        .zip(names)
        .map(|(p, n)| AxisModel {
            name: n,
            servo: &p.servo,
            structure: p.structure,
        })
        .collect();
    let period = plants.first().map_or(0.0, |p| p.period_s);
    prior
        .apply(&models, period, cmd, linear)
        .map_err(|e| Error::Effects(e.to_string()))
}

/// Backlash between motor and table as a play (hysteresis) operator of width `b` (mm):
/// the table stays put while the motor moves inside the gap and is dragged at `motor ∓ b/2`
/// once the gap is closed. `c0` (mm, clamped to ±b/2) is the initial table − motor offset.
///
/// `table_i = clamp(table_{i−1}, motor_i − b/2, motor_i + b/2)`.
/// Reference: Krasnosel'skii & Pokrovskii, "Systems with Hysteresis" (1989), the play
/// operator; semi-closed loop: the servo closes on the motor, the table is what is measured.
pub fn play(motor: &[f64], b: f64, c0: f64) -> Vec<f64> {
    let half = 0.5 * b.max(0.0);
    let mut out = Vec::with_capacity(motor.len());
    let Some(&m0) = motor.first() else { return out };
    let mut table = m0 + c0.clamp(-half, half);
    for &m in motor {
        table = table.clamp(m - half, m + half);
        out.push(table);
    }
    out
}

#[cfg(test)]
mod tests;
