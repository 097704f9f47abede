//! Stage 4 of the loop search: the points between the loops follow the loops' timing.
//!
//! The points outside the loops come from the main iteration, which pre-distorted them for
//! the original's timing: where the original braked for a corner, on an arc before it, they
//! correct the small radial error of a slow pass. The loops run the corners faster, so the
//! command no longer brakes there and those points are wrong for it (on the line–half circle
//! R 10–line program at F 3000, kv 60, 1.4–2.4 µm of distance-weighted error per mm of the
//! arc before the second corner). This stage repeats the main iteration's step on them
//! (each point moved against the smoothed mean error of the samples near it, module
//! `reference`), the loops' points held, and keeps a step when the search's objective falls,
//! halving the step where it does not.

use super::super::limits::turns_above;
use super::super::reference::{correction, smooth};
use super::super::run::{Eval, Run, round_to};
use super::super::{BREAK_RAD, Error, POSITION_DECIMALS, SMOOTH_PERIODS};
use super::descent::Best;

/// Most steps of the stage.
const STEPS: usize = 8;

/// Runs the stage on `best` (its arrays describe the run's points on entry), updating it.
/// `score` is the search's objective of a simulation; `fixed(k)` marks points that may not
/// move (a kept line's); `count(e)` books a simulation. The stage runs at most [`STEPS`]
/// simulations, beyond the search's work bound (it must follow the loops the search found).
pub(super) fn settle(
    run: &mut Run,
    best: &mut Best,
    score: &dyn Fn(&Run, &Eval) -> f64,
    fixed: &dyn Fn(usize) -> bool,
    count: &dyn Fn(&Eval),
) -> Result<(), Error> {
    best.1.install(run);
    let arr = &best.1;
    let m = arr.pts.len();
    let half_mm: Vec<f64> = arr
        .base_feed
        .iter()
        .map(|f| SMOOTH_PERIODS * run.period_s * f / 60.0)
        .collect();
    let turns = turns_above(run.start, &arr.pts, BREAK_RAD);
    let brk: Vec<bool> = (0..m).map(|k| turns[k] || arr.in_loop[k]).collect();
    let still: Vec<bool> = (0..m)
        .map(|k| k + 1 == m || arr.in_loop[k] || fixed(k))
        .collect();
    let mut pts = arr.pts.clone();
    let mut alpha = 1.0;
    for _ in 0..STEPS {
        let corr = smooth(
            &correction(&arr.sigma, &best.2.feet),
            &arr.sigma,
            &half_mm,
            &brk,
        );
        let cand: Vec<[f64; 3]> = (0..m)
            .map(|k| {
                if still[k] {
                    pts[k]
                } else {
                    std::array::from_fn(|d| {
                        round_to(pts[k][d] - alpha * corr[k][d], POSITION_DECIMALS)
                    })
                }
            })
            .collect();
        let e = run.evaluate(&cand)?;
        count(&e);
        let s = score(run, &e);
        if s < best.0 - 1e-9 {
            pts = cand;
            best.0 = s;
            best.2 = e;
        } else {
            alpha *= 0.5;
            if alpha < 0.25 {
                break;
            }
        }
    }
    best.1.pts = pts;
    Ok(())
}
