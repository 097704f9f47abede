//! The bounds of the fits' searches (friction, gain, backlash, cyclic pitch, thermal time
//! constant) and which fitted parameters ended at one. Bounds only stop a runaway search: a
//! fit at a first bound is refitted once within the wide bounds (`fit::fit`), and only a
//! parameter still at a wide bound is not a finding. No bound judges a size (issue 23).

use crate::gap::effects::Fitted;
use crate::gap::plant::AxisPlant;

/// Friction giving a static error of 0.1 mm for one axis: `0.1·kp_v·kv` mm/s² (cascade) or
/// `0.1·kv` mm/s (first-order loop), the first search's upper bound.
pub fn friction_max(p: &AxisPlant) -> f64 {
    match p.servo.kp_v {
        Some(kp) => kp * p.servo.kv * 0.1,
        None => p.servo.kv * 0.1,
    }
}

/// The bounds of the searches that have them (the linear fits have none). They exist only to
/// stop a runaway search, never to veto a size: a fit that ends at a bound of
/// [`SearchBounds::FIRST`] is refitted once within [`SearchBounds::WIDE`] (see [`crate::gap::fit::fit`]), and
/// only a parameter still at a wide bound is named by [`at_bound`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SearchBounds {
    /// Friction bound as a multiple of [`friction_max`].
    pub friction_factor: f64,
    /// Position-loop gain, as ratios to the stored gain.
    pub kv_ratio: (f64, f64),
    /// Largest backlash, mm.
    pub backlash_max_mm: f64,
    /// Cyclic-error pitch, mm (the top is also cut at 2/3 of the travel).
    pub pitch_mm: (f64, f64),
    /// Shortest thermal time constant, as a fraction of the block's duration.
    pub tau_min_fraction: f64,
}

impl SearchBounds {
    /// The first search: static friction lag 0.1 mm, gain 0.5–2×, backlash 0.25 mm, pitch
    /// 0.5–64 mm, τ ≥ 5 % of the block.
    pub const FIRST: SearchBounds = SearchBounds {
        friction_factor: 1.0,
        kv_ratio: (0.5, 2.0),
        backlash_max_mm: 0.25,
        pitch_mm: (0.5, 64.0),
        tau_min_fraction: 0.05,
    };
    /// The widened search: static friction lag 1 mm, gain 0.2–5×, backlash 1 mm, pitch
    /// 0.125–256 mm, τ ≥ 1.25 % of the block.
    pub const WIDE: SearchBounds = SearchBounds {
        friction_factor: 10.0,
        kv_ratio: (0.2, 5.0),
        backlash_max_mm: 1.0,
        pitch_mm: (0.125, 256.0),
        tau_min_fraction: 0.0125,
    };
}

fn near(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * b.abs().max(1e-12)
}

/// Names (as in [`Fitted::params`]) of the parameters that ended at a bound of the search
/// `bounds`: friction at `friction_factor·`[`friction_max`], gain ratio at either end of
/// `kv_ratio`, backlash at `backlash_max_mm`, pitch at either end of `pitch_mm`, τ at
/// `tau_min_fraction` of `duration_s`. Such a value is where the search stopped, not a
/// measurement of the machine. [`at_bound`] asks this of [`SearchBounds::WIDE`].
pub fn at_bound_of(
    fitted: &Fitted,
    axes: &[String],
    plants: &[AxisPlant],
    duration_s: f64,
    bounds: &SearchBounds,
) -> Vec<String> {
    let ax = |k: usize| {
        axes.get(k)
            .map_or_else(|| format!("axis{k}"), |a| a.to_lowercase())
    };
    let mut out = Vec::new();
    match fitted {
        Fitted::CoulombFriction { f } => {
            for (k, &f) in f.iter().enumerate() {
                if near(f, bounds.friction_factor * friction_max(&plants[k])) {
                    let unit = if plants[k].has_velocity_loop() {
                        "accel_mm_s2"
                    } else {
                        "velocity_deficit_mm_s"
                    };
                    out.push(format!("{}_{unit}", ax(k)));
                }
            }
        }
        Fitted::ServoGainMismatch { kv } => {
            for (k, &kv) in kv.iter().enumerate() {
                let r = kv / plants[k].servo.kv;
                if near(r, bounds.kv_ratio.0) || near(r, bounds.kv_ratio.1) {
                    out.push(format!("{}_kv_per_s", ax(k)));
                    out.push(format!("{}_kv_ratio", ax(k)));
                }
            }
        }
        Fitted::Backlash { b, .. } => {
            for (k, &b) in b.iter().enumerate() {
                if near(b, bounds.backlash_max_mm) {
                    out.push(format!("{}_mm", ax(k)));
                }
            }
        }
        Fitted::CyclicError { pitch, sin, cos } => {
            for (k, &p) in pitch.iter().enumerate() {
                let active = sin[k] != 0.0 || cos[k] != 0.0;
                if active && (near(p, bounds.pitch_mm.0) || near(p, bounds.pitch_mm.1)) {
                    out.push(format!("{}_pitch_mm", ax(k)));
                }
            }
        }
        Fitted::ThermalDrift { tau, .. } if near(*tau, bounds.tau_min_fraction * duration_s) => {
            out.push("tau_s".to_string());
        }
        _ => {}
    }
    out
}

/// The parameters still at a bound after the widened search ([`SearchBounds::WIDE`]): a
/// runaway, not a finding (see [`at_bound_of`]).
pub fn at_bound(
    fitted: &Fitted,
    axes: &[String],
    plants: &[AxisPlant],
    duration_s: f64,
) -> Vec<String> {
    at_bound_of(fitted, axes, plants, duration_s, &SearchBounds::WIDE)
}
