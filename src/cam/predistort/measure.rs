//! Figures of a simulated run against the original path beyond the per-period RMS and max:
//! the distance-weighted RMS (issue 24's measure) and the gouge at corners.
//!
//! The per-period RMS weights every interpolation period alike, so the periods a program
//! spends braking into a corner or standing at its end count as much as cruising ones. The
//! distance-weighted RMS weights each period's error by the length of path the tool tip
//! covers around it, i.e. it is the RMS of the error along the cut surface.

use super::corners::{self, CornerSpot};
use super::reference::Reference;
use super::{ErrorStats, Run, norm, sub};

/// Path length (mm) each tool tip of `tips` (mm, one per period) stands for: half the
/// chord to each neighbour.
pub(super) fn path_weights(tips: &[[f64; 3]]) -> Vec<f64> {
    let n = tips.len();
    (0..n)
        .map(|i| {
            let back = if i > 0 {
                norm(sub(tips[i], tips[i - 1]))
            } else {
                0.0
            };
            let fwd = if i + 1 < n {
                norm(sub(tips[i + 1], tips[i]))
            } else {
                0.0
            };
            0.5 * (back + fwd)
        })
        .collect()
}

/// Distance-weighted RMS (mm) of the contour errors `ce` (mm, one per period) of the tool
/// tip path `tips` (mm): `√(Σ wᵢ ceᵢ² / Σ wᵢ)` with `wᵢ` the path length around period `i`
/// ([`path_weights`]), the trapezoidal rule for `√(∫ ce² ds / ∫ ds)` along the actual
/// path. Falls back to the per-period RMS when the tip never moves.
pub(super) fn distance_weighted_rms(ce: &[f64], tips: &[[f64; 3]]) -> f64 {
    let w = path_weights(tips);
    let total: f64 = w.iter().sum();
    if total <= 0.0 {
        let n = ce.len().max(1) as f64;
        return (ce.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    }
    (ce.iter().zip(&w).map(|(v, w)| w * v * v).sum::<f64>() / total).sqrt()
}

/// Tool tips (mm) of simulated machine axes (columns X, Y, Z).
pub(super) fn tips_of(actual: &[Vec<f64>]) -> Vec<[f64; 3]> {
    (0..actual[0].len())
        .map(|i| [actual[0][i], actual[1][i], actual[2][i]])
        .collect()
}

/// Signed distance (mm) of an actual tool tip beyond the original path on the *outer* side
/// of a corner's turn — into the material when the corner is an inside corner (a pocket's),
/// where the material lies outside the turn. `foot_s` is the arc parameter of the tip's foot
/// on `reference`, `e` the tip minus its foot, `inside` the unit vector into the turn at the
/// corner (`d_out − d_in` normalized). Positive values are gouges.
///
/// Formula: `g = −e·n`, `n` the unit normal of the reference segment at the foot, in the
/// direction of `inside` (its component perpendicular to the segment).
pub(super) fn outward_offset(
    reference: &Reference,
    foot_s: f64,
    e: [f64; 3],
    inside: [f64; 3],
) -> f64 {
    let k = reference.knots.len();
    if k < 2 {
        return 0.0;
    }
    let j = reference
        .cum
        .partition_point(|c| *c <= foot_s)
        .clamp(1, k - 1);
    let t = sub(reference.knots[j], reference.knots[j - 1]);
    let lt = norm(t);
    if lt <= 0.0 {
        return 0.0;
    }
    let t = t.map(|v| v / lt);
    let dot = inside[0] * t[0] + inside[1] * t[1] + inside[2] * t[2];
    let n = std::array::from_fn::<f64, 3, _>(|d| inside[d] - dot * t[d]);
    let ln = norm(n);
    if ln <= 1e-9 {
        return 0.0;
    }
    -(e[0] * n[0] + e[1] * n[1] + e[2] * n[2]) / ln
}

/// The figures of a run whose contour errors (motion core, one per period) are `ce` and
/// simulated axes `actual`, its command `periods` long.
pub(super) fn stats(
    run: &Run,
    spots: &[CornerSpot],
    ce: &[f64],
    actual: &[Vec<f64>],
    periods: usize,
) -> ErrorStats {
    let tips = tips_of(actual);
    let gouge = if spots.is_empty() {
        0.0
    } else {
        corners::gouge(&run.reference, spots, &run.reference.feet(&tips))
    };
    let sq = ce.iter().map(|v| v * v).sum::<f64>();
    ErrorStats {
        rms_mm: (sq / ce.len().max(1) as f64).sqrt(),
        max_mm: ce.iter().fold(0.0f64, |m, v| m.max(*v)),
        rms_distance_mm: distance_weighted_rms(ce, &tips),
        gouge_mm: gouge,
        duration_s: periods as f64 * run.period_s,
    }
}
