//! The set of machine models an answer is judged on (issue 39 item 3): the machine as
//! defined, and the ways a real machine commonly differs from its definition.

use crate::motion::Machine;

/// Relative spread of the position-loop gain kv: tuning sheets and the drives' own
/// auto-tuning differ from the commissioned value by about this much (±15 %, issue 39).
pub const KV_SPREAD: f64 = 0.15;

/// Spread of the velocity feed-forward fraction kff (absolute, ±0.1, issue 39): drives are
/// often run at a feed-forward other than the one recorded with the machine.
pub const KFF_SPREAD: f64 = 0.1;

/// The controller's interpolation period may be a fraction of the one the model is built
/// with (a 1 ms model of a 0.5 ms controller): the planner's segment cap and the
/// sampling of corners change with it.
pub const PERIOD_FACTOR: f64 = 0.5;

/// One model of the set.
#[derive(Clone, Debug)]
pub struct Model {
    /// What differs from the definition, e.g. "kv -15 %"; "nominal" for the definition.
    pub name: String,
    /// The machine.
    pub machine: Machine,
    /// Interpolation period, s.
    pub period_s: f64,
}

/// The model set of `machine` at `period_s` (s): nominal first, then kv ×(1 ∓ 15 %), kff
/// ∓ 0.1 (within 0..1; a change that clipping makes void is left out), and the period
/// ×0.5 (where that stays at or above the interpolator's 10 µs).
pub fn model_set(machine: &Machine, period_s: f64) -> Vec<Model> {
    let mut out = vec![Model {
        name: "nominal".into(),
        machine: machine.clone(),
        period_s,
    }];
    for (name, f) in [("kv -15 %", 1.0 - KV_SPREAD), ("kv +15 %", 1.0 + KV_SPREAD)] {
        let mut m = machine.clone();
        for a in &mut m.axes {
            a.servo.kv *= f;
        }
        out.push(Model {
            name: name.into(),
            machine: m,
            period_s,
        });
    }
    for (name, d) in [("kff -0.1", -KFF_SPREAD), ("kff +0.1", KFF_SPREAD)] {
        let mut m = machine.clone();
        let mut changed = false;
        for a in &mut m.axes {
            let k = (a.servo.kff + d).clamp(0.0, 1.0);
            changed |= k != a.servo.kff;
            a.servo.kff = k;
        }
        if changed {
            out.push(Model {
                name: name.into(),
                machine: m,
                period_s,
            });
        }
    }
    // The interpolator's shortest period is 10 µs.
    if period_s * PERIOD_FACTOR >= 1e-5 {
        out.push(Model {
            name: "period x0.5".into(),
            machine: machine.clone(),
            period_s: period_s * PERIOD_FACTOR,
        });
    }
    out
}
