//! Truth plants outside the effects library (issue 23, item 2): stick-slip, a resonance, a
//! bent screw, a loose gib, a wrong kinematic parameter and a sensor fault, beside the two
//! older ones of [`crate::gap::truth`] (velocity-loop gain, straightness). None of them is a
//! library effect at any size, so "none of these" (`unexplained`) is the right answer unless a
//! library effect happens to remove most of the held-out gap.
//!
//! Each is applied to the independent RK4 truth plant's table positions
//! ([`crate::gap::truth::measure`] of `Truth::None`) and drawn at sizes comparable to the
//! library truths (gaps of a few µm to a few tens of µm).

use rand::{Rng, RngExt};

use crate::gap::truth::{Truth, measure as measure_truth};
use crate::motion::ServoAxis;

/// An out-of-library effect.
#[derive(Clone, Debug, PartialEq)]
pub enum Outside {
    /// Quasi-static stick-slip of a compliant drive on `axis`: the table sticks until the drive
    /// is wound up by `static_mm`, then slips past the kinetic equilibrium `kinetic_mm` (mm)
    /// to a wind-up of `2·kinetic − static` (a mass-spring with Coulomb friction; Armstrong-
    /// Hélouvry, Dupont & Canudas de Wit 1994, §3.1): a sawtooth periodic in position.
    StickSlip {
        /// Affected axis.
        axis: usize,
        /// Wind-up at which the table breaks away, mm.
        static_mm: f64,
        /// Wind-up that kinetic friction holds, mm.
        kinetic_mm: f64,
    },
    /// A lightly damped mode between motor and table on `axis` (`x'' = ω²(m − x) − 2ζωx'`),
    /// its departure from the motor scaled so its peak is `peak_mm`.
    Resonance {
        /// Affected axis.
        axis: usize,
        /// Mode frequency, Hz.
        freq_hz: f64,
        /// Damping ratio.
        damping: f64,
        /// Peak of the table's departure from the motor, mm.
        peak_mm: f64,
    },
    /// A bent screw of `axis`: the nut's lateral runout once per revolution moves the other
    /// axis by `amplitude·bow·sin(2π·x/lead + phase)`, `bow` largest mid-travel.
    BentScrew {
        /// Axis whose screw is bent.
        axis: usize,
        /// Screw lead, mm.
        lead_mm: f64,
        /// Runout at mid-travel, mm.
        amplitude_mm: f64,
        /// Phase, rad.
        phase: f64,
    },
    /// A loose gib of `axis`: the carriage shifts sideways (on the other axis) by
    /// `±shift/2` with `axis`' direction of motion, settling with time constant `tau_s`.
    LooseGib {
        /// Axis whose gib is loose.
        axis: usize,
        /// Sideways shift between the two directions, mm.
        shift_mm: f64,
        /// Settling time constant, s.
        tau_s: f64,
    },
    /// A wrong kinematic parameter (the transform's pivot placed wrongly): X is displaced by
    /// `k·(x − x̄)(y − ȳ)` and Y by `−k·(x − x̄)²/2`, 1/mm, about the block's mean position.
    WrongKinematics {
        /// Coupling, 1/mm.
        k: f64,
    },
    /// A sensor fault on `axis`: lost counts (a lasting step of `step_mm` at a fraction
    /// `at` of the block) and single-sample spikes.
    SensorFault {
        /// Affected axis.
        axis: usize,
        /// Where the step happens, as a fraction of the block.
        at: f64,
        /// Step, mm.
        step_mm: f64,
        /// (fraction of the block, size mm) of each spike.
        spikes: Vec<(f64, f64)>,
    },
}

/// The out-of-library kinds drawn (the two older ones of `Truth` plus the six of [`Outside`]).
pub const KINDS: usize = 8;

/// Draws an out-of-library truth for these stored servo axes: uniformly one of the [`KINDS`]
/// kinds (a velocity-loop gain only where there is a velocity loop, else a straightness).
pub fn draw(servo: &[ServoAxis], rng: &mut impl Rng) -> Truth {
    let d = servo.len();
    let sign = |rng: &mut dyn rand::Rng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let axis = rng.random_range(0..d.min(2));
    match rng.random_range(0..KINDS) {
        0 if servo[axis].kp_v.is_some() => {
            Truth::VelocityLoopGain(axis, rng.random_range(0.4..0.7))
        }
        0 | 1 => Truth::Straightness(sign(rng) * rng.random_range(2e-6..6e-6), 0.0),
        2 => {
            let static_mm = rng.random_range(0.004..0.015);
            Truth::Outside(Outside::StickSlip {
                axis,
                static_mm,
                kinetic_mm: static_mm / rng.random_range(2.5..6.0),
            })
        }
        3 => Truth::Outside(Outside::Resonance {
            axis,
            freq_hz: rng.random_range(8.0..40.0),
            damping: rng.random_range(0.02..0.1),
            peak_mm: rng.random_range(0.005..0.020),
        }),
        4 => Truth::Outside(Outside::BentScrew {
            axis,
            lead_mm: [5.0, 10.0, 16.0, 20.0][rng.random_range(0..4)],
            amplitude_mm: rng.random_range(0.004..0.015),
            phase: rng.random_range(0.0..std::f64::consts::TAU),
        }),
        5 => Truth::Outside(Outside::LooseGib {
            axis,
            shift_mm: rng.random_range(0.004..0.020),
            tau_s: rng.random_range(0.02..0.1),
        }),
        6 => Truth::Outside(Outside::WrongKinematics {
            k: sign(rng) * rng.random_range(1e-5..4e-5),
        }),
        _ => {
            let spikes = (0..rng.random_range(3..10))
                .map(|_| {
                    (
                        rng.random_range(0.0..1.0),
                        sign(rng) * rng.random_range(0.01..0.05),
                    )
                })
                .collect();
            Truth::Outside(Outside::SensorFault {
                axis,
                at: rng.random_range(0.2..0.8),
                step_mm: sign(rng) * rng.random_range(0.005..0.020),
                spikes,
            })
        }
    }
}

/// The other axis of a pair (1 for 0, else 0).
fn other(axis: usize) -> usize {
    if axis == 0 { 1 } else { 0 }
}

/// Measured positions (per axis, mm) of the truth plant with `outside` for the command
/// `cmd`, plus Gaussian noise `sigma` (mm).
pub fn measure(
    servo: &[ServoAxis],
    outside: &Outside,
    cmd: &[Vec<f64>],
    period: f64,
    sigma: f64,
    rng: &mut impl Rng,
) -> Vec<Vec<f64>> {
    let mut pos = measure_truth(servo, &Truth::None, cmd, period, 0.0, rng);
    let n = pos.first().map_or(0, Vec::len);
    match outside {
        Outside::StickSlip {
            axis,
            static_mm,
            kinetic_mm,
        } => {
            let col = &mut pos[*axis];
            let mut table = col.first().copied().unwrap_or(0.0);
            for x in col.iter_mut() {
                let wind = *x - table;
                if wind.abs() > *static_mm {
                    table = *x - wind.signum() * (2.0 * kinetic_mm - static_mm);
                }
                *x = table;
            }
        }
        Outside::Resonance {
            axis,
            freq_hz,
            damping,
            peak_mm,
        } => {
            let motor = pos[*axis].clone();
            let w = std::f64::consts::TAU * freq_hz;
            let sub = 32;
            let h = period / sub as f64;
            let (mut x, mut v) = (motor.first().copied().unwrap_or(0.0), 0.0);
            let mut dep = vec![0.0; n];
            for i in 0..n {
                let m0 = motor[i.saturating_sub(1)];
                for s in 0..sub {
                    let m = m0 + (motor[i] - m0) * (s + 1) as f64 / sub as f64;
                    // semi-implicit Euler, stable for ω·h ≪ 1 (ω·h ≤ 0.008 here)
                    v += h * (w * w * (m - x) - 2.0 * damping * w * v);
                    x += h * v;
                }
                dep[i] = x - motor[i];
            }
            let peak = dep.iter().fold(0.0f64, |a, d| a.max(d.abs()));
            if peak > 0.0 {
                for (p, d) in pos[*axis].iter_mut().zip(&dep) {
                    *p += d * peak_mm / peak;
                }
            }
        }
        Outside::BentScrew {
            axis,
            lead_mm,
            amplitude_mm,
            phase,
        } => {
            let x = pos[*axis].clone();
            let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &v| {
                (a.0.min(v), a.1.max(v))
            });
            let span = (hi - lo).max(1e-9);
            for (y, &x) in pos[other(*axis)].iter_mut().zip(&x) {
                let bow = 0.5 + 0.5 * (std::f64::consts::PI * (x - lo) / span).sin();
                *y += amplitude_mm * bow * (std::f64::consts::TAU * x / lead_mm + phase).sin();
            }
        }
        Outside::LooseGib {
            axis,
            shift_mm,
            tau_s,
        } => {
            let c = &cmd[*axis];
            let (mut dir, mut shift) = (0.0, 0.0);
            let alpha = 1.0 - (-period / tau_s).exp();
            let target = other(*axis);
            for i in 0..n {
                let v = if i + 1 < n { c[i + 1] - c[i] } else { 0.0 };
                if v.abs() > 1e-9 {
                    dir = v.signum();
                }
                shift += alpha * (dir * shift_mm / 2.0 - shift);
                pos[target][i] += shift;
            }
        }
        Outside::WrongKinematics { k } => {
            let mean = |c: &[f64]| c.iter().sum::<f64>() / c.len().max(1) as f64;
            let (xm, ym) = (mean(&cmd[0]), mean(&cmd[1]));
            let (x, y) = (pos[0].clone(), pos[1].clone());
            for i in 0..n {
                let (dx, dy) = (x[i] - xm, y[i] - ym);
                pos[0][i] += k * dx * dy;
                pos[1][i] -= k * dx * dx / 2.0;
            }
        }
        Outside::SensorFault {
            axis,
            at,
            step_mm,
            spikes,
        } => {
            let index = |f: f64| ((f * n as f64) as usize).min(n.saturating_sub(1));
            for x in pos[*axis].iter_mut().skip(index(*at)) {
                *x += step_mm;
            }
            for &(f, s) in spikes {
                if let Some(x) = pos[*axis].get_mut(index(f)) {
                    *x += s;
                }
            }
        }
    }
    let normal = rand_distr::Normal::new(0.0, sigma.max(1e-12)).expect("valid sigma");
    for col in pos.iter_mut() {
        for x in col.iter_mut() {
            *x += rng.sample(normal);
        }
    }
    pos
}

#[cfg(test)]
mod tests;
