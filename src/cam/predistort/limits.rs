//! The interpolator's junction rule seen from a G01 polyline: the speed limit at each
//! junction from the axes' `max_accel`, where the polyline turns, and the refusal of
//! iteration steps that would make a junction slower than the undistorted polyline's.

use super::{JUNCTION_SLACK, POSITION_DECIMALS, Run, norm, round_to, sub};
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

/// Points on either side of a refused junction over which the step is tapered.
const TAPER_POINTS: usize = 8;

/// Shrinks the step `cur → cand` around every junction whose speed limit from `max_accel`
/// falls below both the feed and the undistorted polyline's limit `init` (by more than
/// [`JUNCTION_SLACK`]): the step is taken back at the junction and tapered in linearly over
/// [`TAPER_POINTS`] points on either side, so that no new kink appears beside it. Counts the
/// refusals per point (with the limiting axis) in `refused`; after 40 passes that still find
/// such junctions the whole step is taken back.
pub(super) fn refuse_sharp_junctions(
    run: &Run,
    init: &[(f64, usize)],
    cur: &[[f64; 3]],
    cand: &mut [[f64; 3]],
    refused: &mut [(usize, usize)],
) {
    let m = cand.len();
    let step: Vec<[f64; 3]> = (0..m).map(|k| sub(cand[k], cur[k])).collect();
    let mut w = vec![1.0f64; m];
    for _pass in 0..40 {
        let feeds = run.feeds(cand);
        let lim = junction_limits(run.machine, run.period_s, run.start, cand);
        let mut any = false;
        for k in 0..m.saturating_sub(1) {
            let need = feeds[k].min(feeds[k + 1]) / 60.0;
            let floor = need.min(init[k].0) * (1.0 - JUNCTION_SLACK);
            if lim[k].0 < floor {
                any = true;
                refused[k].0 += 1;
                refused[k].1 = lim[k].1;
                let lo = k.saturating_sub(TAPER_POINTS);
                let hi = (k + 1 + TAPER_POINTS).min(m - 1);
                // Refused again: halve the whole window's step as well.
                let again = w[k] == 0.0;
                for (j, wj) in w.iter_mut().enumerate().take(hi + 1).skip(lo) {
                    let d = if j <= k { k - j } else { j - k - 1 };
                    *wj = wj.min(d as f64 / (TAPER_POINTS + 1) as f64);
                    if again {
                        *wj *= 0.5;
                    }
                }
            }
        }
        if !any {
            return;
        }
        for k in 0..m {
            cand[k] =
                std::array::from_fn(|d| round_to(cur[k][d] + w[k] * step[k][d], POSITION_DECIMALS));
        }
    }
    cand.copy_from_slice(cur);
}
