//! The interpolator's junction rule seen from a G01 polyline: the speed limit at each
//! junction from the axes' `max_accel`, and where the polyline turns.

use super::{norm, sub};
use crate::motion::Machine;

/// Speed limit (mm/s) of the junction at the end of each G01 segment of the polyline `start`,
/// `pts` from the axes' `max_accel` (mm/s²) and the period `period_s` (s), the interpolator's
/// rule `max_accel·period/|Δ(dq/ds)|` (Zhang & Chen 2025 §2.2 look-ahead as implemented in
/// [`crate::motion::interpolate`]), with the index of the axis that sets it; the last point
/// (the end, a stop) gets infinity.
pub(super) fn junction_limits(
    machine: &Machine,
    period_s: f64,
    start: [f64; 3],
    pts: &[[f64; 3]],
) -> Vec<(f64, usize)> {
    let m = pts.len();
    let dir = |k: usize| {
        let a = if k == 0 { start } else { pts[k - 1] };
        let d = sub(pts[k], a);
        let l = norm(d);
        if l > 0.0 { d.map(|v| v / l) } else { [0.0; 3] }
    };
    (0..m)
        .map(|k| {
            if k + 1 >= m {
                return (f64::INFINITY, 0);
            }
            let (a, b) = (dir(k), dir(k + 1));
            let mut best = (f64::INFINITY, 0);
            for (i, ax) in machine.axes.iter().enumerate().take(3) {
                let dd = (b[i] - a[i]).abs();
                if dd > 1e-12 {
                    let v = ax.limits.max_accel * period_s / dd;
                    if v < best.0 {
                        best = (v, i);
                    }
                }
            }
            best
        })
        .collect()
}

/// Whether the polyline `start`, `pts` turns by more than `rad` (rad) at each point (the last
/// point, the end, counts as a turn).
pub(super) fn turns_above(start: [f64; 3], pts: &[[f64; 3]], rad: f64) -> Vec<bool> {
    let m = pts.len();
    (0..m)
        .map(|k| {
            if k + 1 >= m {
                return true;
            }
            let a = sub(pts[k], if k == 0 { start } else { pts[k - 1] });
            let b = sub(pts[k + 1], pts[k]);
            let (na, nb) = (norm(a), norm(b));
            if na == 0.0 || nb == 0.0 {
                return false;
            }
            let cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (na * nb);
            cos.clamp(-1.0, 1.0).acos() > rad
        })
        .collect()
}
