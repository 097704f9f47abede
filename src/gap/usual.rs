//! The sizes each library effect usually has on a machine tool, and what commonly causes a
//! fitted size far outside them (issue 23, item 1: no veto by size).
//!
//! A fit outside its usual range is never discarded: the held-out score decides between
//! effects, and the answer carries a warning that says why the size is unusual and where to
//! look. A scale error of 4,000 ppm is no machine's geometry, but it is exactly what a wrong
//! lead-screw pitch parameter, a wrong encoder resolution or a tilted measuring device
//! produce; vetoing it made the diagnosis name a much weaker effect instead.

use crate::gap::effects::{Fitted, thermal_basis};
use crate::gap::plant::AxisPlant;

/// Usual |scale error| of a machine axis (50 ppm = 0.05 mm/m).
pub const USUAL_SCALE: f64 = 50e-6;
/// Usual |squareness| between two axes, rad (100 µrad = 0.1 mm/m).
pub const USUAL_SQUARENESS_RAD: f64 = 100e-6;
/// Usual cyclic-error amplitude, mm.
pub const USUAL_CYCLIC_MM: f64 = 0.010;
/// Usual thermal drift over one logged block, mm.
pub const USUAL_DRIFT_MM: f64 = 0.050;
/// Usual backlash (lost motion) of an axis, mm.
pub const USUAL_BACKLASH_MM: f64 = 0.030;
/// Usual ratio of the actual to the stored position-loop gain.
pub const USUAL_KV_RATIO: (f64, f64) = (0.7, 1.4);
/// Usual static following error that friction causes through the loop gains, mm.
pub const USUAL_FRICTION_LAG_MM: f64 = 0.010;

/// `v` with `decimals` decimals, thousands grouped by commas and a true minus sign
/// ("−4,006"), as the warnings print sizes.
pub fn grouped(v: f64, decimals: usize) -> String {
    let text = format!("{:.*}", decimals, v.abs());
    let (int, frac) = text.split_once('.').map_or((text.as_str(), ""), |p| p);
    let mut out = String::new();
    for (i, ch) in int.chars().enumerate() {
        if i > 0 && (int.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(ch);
    }
    if !frac.is_empty() {
        out.push('.');
        out.push_str(frac);
    }
    if v < 0.0 && text.chars().any(|c| c.is_ascii_digit() && c != '0') {
        out.insert(0, '−');
    }
    out
}

/// "far above" when `ratio` (size / usual limit) is 10 or more, else "above".
fn how_far(ratio: f64) -> &'static str {
    if ratio >= 10.0 { "far above" } else { "above" }
}

/// One warning per fitted size outside its usual range (empty when every size is usual):
/// which size, how far from the usual range, and what commonly causes it. `axes` are the axis
/// letters, `plants` the stored models (for the gain and the friction's static lag),
/// `duration_s` the block's length (for the drift).
///
/// Formula: friction's static lag is `f / (kp_v·kv)` mm for a cascade (`f` in mm/s²) and
/// `f / kv` mm for a first-order loop (`f` in mm/s); drift over the block is
/// `rate·τ·(1 − e^{−T/τ})`. Reference: usual sizes from ISO 230-2 acceptance practice
/// (positioning errors of tens of µm per metre) and machine builders' backlash and
/// squareness tolerances. Known bad cases: a usual size can still be wrong (the warning
/// catches the gross errors only).
pub fn warnings(
    fitted: &Fitted,
    axes: &[String],
    plants: &[AxisPlant],
    duration_s: f64,
) -> Vec<String> {
    let ax = |k: usize| axes.get(k).cloned().unwrap_or_else(|| format!("axis {k}"));
    let mut out = Vec::new();
    match fitted {
        Fitted::None => {}
        Fitted::ScaleError { s } => {
            for (k, &s) in s.iter().enumerate() {
                if s.abs() > USUAL_SCALE {
                    out.push(format!(
                        "scale error {} {} ppm: {} a machine's usual ±{} ppm; check the lead or \
                         pitch parameter, the encoder resolution, or the measuring device's \
                         alignment",
                        ax(k),
                        grouped(s * 1e6, 0),
                        how_far(s.abs() / USUAL_SCALE),
                        grouped(USUAL_SCALE * 1e6, 0)
                    ));
                }
            }
        }
        Fitted::AxisSquareness {
            target,
            source,
            alpha,
        } => {
            if alpha.abs() > USUAL_SQUARENESS_RAD {
                out.push(format!(
                    "axis squareness {} on {} {} µrad: {} a machine's usual ±{} µrad; check the \
                     measuring device's alignment, the order of the log's columns, the \
                     squareness compensation table, or whether a crash shifted the axis",
                    ax(*target),
                    ax(*source),
                    grouped(alpha * 1e6, 0),
                    how_far(alpha.abs() / USUAL_SQUARENESS_RAD),
                    grouped(USUAL_SQUARENESS_RAD * 1e6, 0)
                ));
            }
        }
        Fitted::CyclicError { pitch, sin, cos } => {
            for k in 0..pitch.len() {
                let amp = sin[k].hypot(cos[k]);
                if amp > USUAL_CYCLIC_MM {
                    out.push(format!(
                        "cyclic error {} {} mm amplitude at a {} mm pitch: {} a machine's usual \
                         {} mm; check the encoder signals (interpolation, contamination, \
                         mounting), a bent or damaged screw, or the coupling",
                        ax(k),
                        grouped(amp, 4),
                        grouped(pitch[k], 2),
                        how_far(amp / USUAL_CYCLIC_MM),
                        grouped(USUAL_CYCLIC_MM, 3)
                    ));
                }
            }
        }
        Fitted::ThermalDrift { rate, tau } => {
            for (k, &r) in rate.iter().enumerate() {
                let drift = r * thermal_basis(duration_s, *tau);
                if drift.abs() > USUAL_DRIFT_MM {
                    out.push(format!(
                        "thermal drift {} {} mm over the {} s block: {} a machine's usual {} mm; \
                         check the measuring device (a laser without air compensation drifts), \
                         a fixture or sensor mount that moves, or clocks of log and command \
                         that disagree",
                        ax(k),
                        grouped(drift, 4),
                        grouped(duration_s, 1),
                        how_far(drift.abs() / USUAL_DRIFT_MM),
                        grouped(USUAL_DRIFT_MM, 3)
                    ));
                }
            }
        }
        Fitted::Backlash { b, .. } => {
            for (k, &b) in b.iter().enumerate() {
                if b > USUAL_BACKLASH_MM {
                    out.push(format!(
                        "backlash {} {} mm: {} a machine's usual {} mm; check the backlash \
                         compensation parameter (sign, units, applied twice), a worn nut or \
                         thrust bearing, or a loose coupling",
                        ax(k),
                        grouped(b, 4),
                        how_far(b / USUAL_BACKLASH_MM),
                        grouped(USUAL_BACKLASH_MM, 3)
                    ));
                }
            }
        }
        Fitted::ServoGainMismatch { kv } => {
            for (k, &kv) in kv.iter().enumerate() {
                let Some(p) = plants.get(k) else { continue };
                let ratio = kv / p.servo.kv;
                let (lo, hi) = USUAL_KV_RATIO;
                if !(lo..=hi).contains(&ratio) {
                    out.push(format!(
                        "servo gain {} {}× the stored kv ({} 1/s against {} 1/s): outside a \
                         machine's usual {}–{}×; check the stored kv's units (1 m/min/mm = \
                         16.67 1/s), the active parameter set, or the feed-forward and filter \
                         settings",
                        ax(k),
                        grouped(ratio, 2),
                        grouped(kv, 1),
                        grouped(p.servo.kv, 1),
                        grouped(lo, 1),
                        grouped(hi, 1)
                    ));
                }
            }
        }
        Fitted::CoulombFriction { f } => {
            for (k, &f) in f.iter().enumerate() {
                let Some(p) = plants.get(k) else { continue };
                let lag = match p.servo.kp_v {
                    Some(kp) => f / (kp * p.servo.kv),
                    None => f / p.servo.kv,
                };
                if lag > USUAL_FRICTION_LAG_MM {
                    out.push(format!(
                        "Coulomb friction {}: a static lag of {} mm, {} a machine's usual {} mm; \
                         check the way lubrication, the gib adjustment, a seized bearing, or \
                         the velocity loop's integrator",
                        ax(k),
                        grouped(lag, 4),
                        how_far(lag / USUAL_FRICTION_LAG_MM),
                        grouped(USUAL_FRICTION_LAG_MM, 3)
                    ));
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests;
