//! The effects library (motion domain): one parametric model per openapi.yaml effect name, each
//! added to the simulation and re-simulated.

use serde::{Deserialize, Serialize};

use crate::gap::plant::{AxisPlant, play};

/// openapi.yaml effect names of the motion domain (and `none`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// No unmodelled effect beats the noise.
    None,
    /// Coulomb friction inside the velocity loop.
    CoulombFriction,
    /// Play between motor and table (semi-closed loop).
    Backlash,
    /// A per-axis position-loop gain different from the stored one.
    ServoGainMismatch,
    /// Non-orthogonality of two axes (`x += α·y` or `y += α·x`, ...).
    AxisSquareness,
    /// Linear scale error per axis (`x += s·x`, about machine zero).
    ScaleError,
    /// An error periodic in an axis position (ball-screw lead, encoder).
    CyclicError,
    /// A drift growing with the block's time.
    ThermalDrift,
    /// A verdict, never a fitted effect: the gap is well above the noise and no library
    /// effect (nor the steps together) removes most of it on held-out data.
    Unexplained,
}

impl Effect {
    /// Every effect of the library (without `None`), in a fixed order.
    pub const LIBRARY: [Effect; 7] = [
        Effect::CoulombFriction,
        Effect::Backlash,
        Effect::ServoGainMismatch,
        Effect::AxisSquareness,
        Effect::ScaleError,
        Effect::CyclicError,
        Effect::ThermalDrift,
    ];

    /// The name in openapi.yaml.
    pub fn name(self) -> &'static str {
        match self {
            Effect::None => "none",
            Effect::CoulombFriction => "coulomb_friction",
            Effect::Backlash => "backlash",
            Effect::ServoGainMismatch => "servo_gain_mismatch",
            Effect::AxisSquareness => "axis_squareness",
            Effect::ScaleError => "scale_error",
            Effect::CyclicError => "cyclic_error",
            Effect::ThermalDrift => "thermal_drift",
            Effect::Unexplained => "unexplained",
        }
    }
}

/// Fitted parameters of one effect; vectors are per axis in the machine's axis order.
#[derive(Clone, Debug, PartialEq)]
pub enum Fitted {
    /// Nothing added.
    None,
    /// Friction acceleration mm/s² per axis (mm/s velocity deficit for first-order axes).
    CoulombFriction {
        /// Magnitude per axis.
        f: Vec<f64>,
    },
    /// Backlash width (mm) and where the table starts in the gap, per axis.
    Backlash {
        /// Gap width per axis, mm.
        b: Vec<f64>,
        /// Initial table position in the gap, in units of b/2 along the axis' first motion:
        /// −1 = in contact (lagging the first move), 0 = centred, +1 = leading.
        start: Vec<f64>,
    },
    /// Actual position-loop gain per axis, 1/s.
    ServoGainMismatch {
        /// Gain per axis, 1/s.
        kv: Vec<f64>,
    },
    /// `pos[target] += alpha · pos[source]`, rad.
    AxisSquareness {
        /// Axis that is displaced.
        target: usize,
        /// Axis whose position displaces it.
        source: usize,
        /// Angle, rad.
        alpha: f64,
    },
    /// `pos[k] += s[k] · pos[k]`, dimensionless.
    ScaleError {
        /// Scale per axis.
        s: Vec<f64>,
    },
    /// `pos[k] += a[k]·sin(2π pos/p[k]) + c[k]·cos(2π pos/p[k])`.
    CyclicError {
        /// Pitch per axis, mm.
        pitch: Vec<f64>,
        /// Sine amplitude per axis, mm.
        sin: Vec<f64>,
        /// Cosine amplitude per axis, mm.
        cos: Vec<f64>,
    },
    /// `pos[k] += rate[k] · τ·(1 − e^{−t/τ})` (`rate[k]·t` when τ is infinite).
    ThermalDrift {
        /// Initial drift rate per axis, mm/s.
        rate: Vec<f64>,
        /// Time constant, s (infinite: linear drift).
        tau: f64,
    },
}

/// Sign of an axis' first motion away from its first sample (+1 when it never moves).
pub fn first_direction(x: &[f64]) -> f64 {
    let x0 = x.first().copied().unwrap_or(0.0);
    x.iter()
        .find(|&&v| (v - x0).abs() > 1e-9)
        .map_or(1.0, |v| (v - x0).signum())
}

/// Time basis of the thermal drift: `τ·(1 − e^{−t/τ})`, or `t` for infinite τ (s).
pub fn thermal_basis(t: f64, tau: f64) -> f64 {
    if tau.is_finite() {
        tau * (-(-t / tau).exp_m1())
    } else {
        t
    }
}

/// Phase argument of the cyclic error for position `x` (mm) and pitch `p` (mm): 2π·x/p.
pub fn cyclic_phase(x: f64, p: f64) -> f64 {
    std::f64::consts::TAU * x / p
}

impl Fitted {
    /// Which effect these parameters belong to.
    pub fn effect(&self) -> Effect {
        match self {
            Fitted::None => Effect::None,
            Fitted::CoulombFriction { .. } => Effect::CoulombFriction,
            Fitted::Backlash { .. } => Effect::Backlash,
            Fitted::ServoGainMismatch { .. } => Effect::ServoGainMismatch,
            Fitted::AxisSquareness { .. } => Effect::AxisSquareness,
            Fitted::ScaleError { .. } => Effect::ScaleError,
            Fitted::CyclicError { .. } => Effect::CyclicError,
            Fitted::ThermalDrift { .. } => Effect::ThermalDrift,
        }
    }

    /// Positions (mm, per axis) of the simulation with this effect added, for the command
    /// `cmd` (per axis), given the stored simulation `base` of the same command and the
    /// block's sample period (for the time of thermal drift).
    pub fn predict(
        &self,
        plants: &[AxisPlant],
        cmd: &[Vec<f64>],
        base: &[Vec<f64>],
    ) -> Vec<Vec<f64>> {
        let period = plants.first().map_or(0.0, |p| p.period_s);
        match self {
            Fitted::None => base.to_vec(),
            Fitted::CoulombFriction { f } => plants
                .iter()
                .zip(cmd)
                .zip(f)
                .map(|((p, c), &f)| p.with_friction(f, c))
                .collect(),
            Fitted::Backlash { b, start } => base
                .iter()
                .zip(b)
                .zip(start)
                .map(|((m, &b), &st)| play(m, b, st * 0.5 * b * first_direction(m)))
                .collect(),
            Fitted::ServoGainMismatch { kv } => plants
                .iter()
                .zip(cmd)
                .zip(kv)
                .map(|((p, c), &kv)| p.with_kv(kv, c))
                .collect(),
            Fitted::AxisSquareness {
                target,
                source,
                alpha,
            } => {
                let mut out = base.to_vec();
                for (o, s) in out[*target].iter_mut().zip(&base[*source]) {
                    *o += alpha * s;
                }
                out
            }
            Fitted::ScaleError { s } => base
                .iter()
                .zip(s)
                .map(|(col, &s)| col.iter().map(|x| x + s * x).collect())
                .collect(),
            Fitted::CyclicError { pitch, sin, cos } => base
                .iter()
                .enumerate()
                .map(|(k, col)| {
                    col.iter()
                        .map(|&x| {
                            let ph = cyclic_phase(x, pitch[k]);
                            x + sin[k] * ph.sin() + cos[k] * ph.cos()
                        })
                        .collect()
                })
                .collect(),
            Fitted::ThermalDrift { rate, tau } => base
                .iter()
                .zip(rate)
                .map(|(col, &r)| {
                    col.iter()
                        .enumerate()
                        .map(|(i, &x)| x + r * thermal_basis(i as f64 * period, *tau))
                        .collect()
                })
                .collect(),
        }
    }

    /// Named parameters for the answer (`axes` are the axis letters, lower-cased in names).
    pub fn params(
        &self,
        axes: &[String],
        plants: &[AxisPlant],
        duration_s: f64,
    ) -> Vec<(String, f64)> {
        let ax = |k: usize| {
            axes.get(k)
                .map_or_else(|| format!("axis{k}"), |a| a.to_lowercase())
        };
        let mut out = Vec::new();
        match self {
            Fitted::None => {}
            Fitted::CoulombFriction { f } => {
                for (k, &f) in f.iter().enumerate() {
                    if plants[k].has_velocity_loop() {
                        out.push((format!("{}_accel_mm_s2", ax(k)), f));
                    } else {
                        out.push((format!("{}_velocity_deficit_mm_s", ax(k)), f));
                    }
                }
            }
            Fitted::Backlash { b, start } => {
                for k in 0..b.len() {
                    out.push((format!("{}_mm", ax(k)), b[k]));
                    out.push((format!("{}_start_in_gap", ax(k)), start[k]));
                }
            }
            Fitted::ServoGainMismatch { kv } => {
                for (k, &kv) in kv.iter().enumerate() {
                    out.push((format!("{}_kv_per_s", ax(k)), kv));
                    out.push((format!("{}_kv_ratio", ax(k)), kv / plants[k].servo.kv));
                }
            }
            Fitted::AxisSquareness {
                target,
                source,
                alpha,
            } => {
                out.push((format!("{}_per_{}_rad", ax(*target), ax(*source)), *alpha));
                out.push(("urad".to_string(), alpha * 1e6));
            }
            Fitted::ScaleError { s } => {
                for (k, &s) in s.iter().enumerate() {
                    out.push((format!("{}_ppm", ax(k)), s * 1e6));
                }
            }
            Fitted::CyclicError { pitch, sin, cos } => {
                for k in 0..pitch.len() {
                    out.push((format!("{}_pitch_mm", ax(k)), pitch[k]));
                    out.push((format!("{}_amplitude_mm", ax(k)), sin[k].hypot(cos[k])));
                    out.push((format!("{}_phase_rad", ax(k)), cos[k].atan2(sin[k])));
                }
            }
            Fitted::ThermalDrift { rate, tau } => {
                for (k, &r) in rate.iter().enumerate() {
                    out.push((format!("{}_rate_mm_s", ax(k)), r));
                    out.push((
                        format!("{}_drift_at_end_mm", ax(k)),
                        r * thermal_basis(duration_s, *tau),
                    ));
                }
                if tau.is_finite() {
                    out.push(("tau_s".to_string(), *tau));
                }
            }
        }
        out
    }
}
