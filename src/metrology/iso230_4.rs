//! ISO 230-4:2005 circular tests: circular deviation G, radial deviation F_max and F_min,
//! and circular hysteresis H of a circle run (ballbar or contour-error output).
//!
//! All figures are about the orthogonal least-squares circle ([`super::fit_circle`]), or
//! about a centre the caller gives (an instrument centred on the nominal centre), never
//! about the algebraic fit alone (whose centre is biased on noisy or partial runs).

use std::f64::consts::TAU;

use super::circle::{Circle, fit_circle};
use super::error::Error;

/// The figures of one circle run, mm.
#[derive(Clone, Debug, PartialEq)]
pub struct Circular230_4 {
    /// Circular deviation G: the radial range max |p_i − c| − min |p_i − c| about the
    /// centre c (ISO 230-4:2005 §3.3, least-squares-circle centre), mm.
    pub g: f64,
    /// Largest radial deviation from the nominal radius about c, max(|p_i − c| − R), mm
    /// (ISO 230-4:2005 §3.4).
    pub f_max: f64,
    /// Smallest radial deviation from the nominal radius, min(|p_i − c| − R), mm.
    pub f_min: f64,
    /// The centre used (the fitted one, or the caller's), [x, y] mm.
    pub centre: [f64; 2],
    /// The least-squares radius about that centre (mean |p_i − c|), mm.
    pub radius_fit: f64,
    /// Whether the centre was fitted (`false`: the caller's).
    pub centre_fitted: bool,
    /// Radial deviation |p_i − c| − R of each point, mm.
    pub radial_deviation: Vec<f64>,
}

/// Circular hysteresis of a CW and a CCW run (ISO 230-4:2005 §3.5), mm.
#[derive(Clone, Debug, PartialEq)]
pub struct Hysteresis {
    /// H: the largest radial difference between the two runs at one angle, mm.
    pub h: f64,
    /// The angle of that largest difference about the common centre, degrees from +x.
    pub at_angle_deg: f64,
    /// The common centre, [x, y] mm (orthogonal fit of both runs together, or the caller's).
    pub centre: [f64; 2],
}

fn check_radius(radius: f64) -> Result<(), Error> {
    if radius.is_finite() && radius > 0.0 {
        Ok(())
    } else {
        Err(Error::Invalid {
            field: "radius",
            value: radius,
            reason: "the nominal radius must be a finite number > 0 mm",
        })
    }
}

fn check_centre(centre: Option<[f64; 2]>) -> Result<(), Error> {
    match centre {
        Some(c) if !(c[0].is_finite() && c[1].is_finite()) => Err(Error::NonFinite {
            field: "centre".into(),
            index: usize::from(c[0].is_finite()),
        }),
        _ => Ok(()),
    }
}

/// Evaluates one circle run by ISO 230-4:2005: G, F_max, F_min, the centre and the fitted
/// radius, all mm. `points` are [x, y] mm in the test plane; `radius_mm` the nominal radius;
/// `centre` fixes the centre (else the orthogonal least-squares circle's).
///
/// Formula: r_i = |p_i − c|; G = max r_i − min r_i; F_max = max r_i − R; F_min = min r_i − R;
/// radius_fit = mean r_i (the least-squares radius about c).
///
/// Reference: ISO 230-4:2005 §3.2 to §3.4.
///
/// Known bad cases: G about the least-squares centre is at most a few % above the
/// minimum-zone G the standard also allows; a run over a short arc fits its centre poorly.
pub fn evaluate_circle(
    points: &[[f64; 2]],
    radius_mm: f64,
    centre: Option<[f64; 2]>,
) -> Result<Circular230_4, Error> {
    check_radius(radius_mm)?;
    check_centre(centre)?;
    let fitted = match centre {
        Some(c) => {
            if let Some(index) = points
                .iter()
                .position(|p| !(p[0].is_finite() && p[1].is_finite()))
            {
                return Err(Error::NonFinite {
                    field: "points".into(),
                    index,
                });
            }
            if points.len() < 3 {
                return Err(Error::Degenerate {
                    field: "points",
                    reason: format!("{} points; a circle needs at least 3", points.len()),
                });
            }
            Circle {
                centre: c,
                radius: 0.0,
            }
        }
        None => fit_circle("points", points)?,
    };
    let c = fitted.centre;
    let radii: Vec<f64> = points
        .iter()
        .map(|p| (p[0] - c[0]).hypot(p[1] - c[1]))
        .collect();
    let (lo, hi) = radii
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &r| {
            (lo.min(r), hi.max(r))
        });
    Ok(Circular230_4 {
        g: hi - lo,
        f_max: hi - radius_mm,
        f_min: lo - radius_mm,
        centre: c,
        radius_fit: radii.iter().sum::<f64>() / radii.len() as f64,
        centre_fitted: centre.is_none(),
        radial_deviation: radii.iter().map(|r| r - radius_mm).collect(),
    })
}

/// Angle (radians in [0, 2π)) and radius of each point about `c`, sorted by angle.
fn polar(points: &[[f64; 2]], c: [f64; 2]) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = points
        .iter()
        .map(|p| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            (dy.atan2(dx).rem_euclid(TAU), dx.hypot(dy))
        })
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

/// Radius of a run (sorted polar points) at angle `theta`, linear between the two neighbours
/// (periodic), or `None` where the neighbours are more than `max_gap` radians apart.
fn radius_at(run: &[(f64, f64)], theta: f64, max_gap: f64) -> Option<f64> {
    let k = run.partition_point(|p| p.0 < theta);
    let (a, b) = if k == 0 || k == run.len() {
        let (lo, hi) = (run[run.len() - 1], run[0]);
        (lo, (hi.0 + TAU, hi.1))
    } else {
        (run[k - 1], run[k])
    };
    let t = if theta < a.0 { theta + TAU } else { theta };
    let gap = b.0 - a.0;
    if gap > max_gap {
        return None;
    }
    if gap <= 0.0 {
        return Some(a.1);
    }
    Some(a.1 + (b.1 - a.1) * (t - a.0) / gap)
}

/// Circular hysteresis H of a clockwise and a counter-clockwise run of the same circle:
/// the largest difference of their radii at one angle about a common centre (the orthogonal
/// least-squares circle of both runs together, or `centre`), mm. Each run's radius between
/// its points is linear in the angle; angles where a run has a gap wider than five times its
/// median spacing are skipped.
///
/// Reference: ISO 230-4:2005 §3.5 (circular hysteresis).
///
/// Known bad cases: runs sampled at very different densities resolve a narrow spike in only
/// one of them, which then counts fully as hysteresis.
pub fn circular_hysteresis(
    cw: &[[f64; 2]],
    ccw: &[[f64; 2]],
    centre: Option<[f64; 2]>,
) -> Result<Hysteresis, Error> {
    check_centre(centre)?;
    let c = match centre {
        Some(c) => c,
        None => {
            let both: Vec<[f64; 2]> = cw.iter().chain(ccw).copied().collect();
            fit_circle("points", &both)?.centre
        }
    };
    for (field, run) in [("cw", cw), ("ccw", ccw)] {
        if run.len() < 3 {
            return Err(Error::Degenerate {
                field,
                reason: format!("{} points; a run needs at least 3", run.len()),
            });
        }
    }
    let (a, b) = (polar(cw, c), polar(ccw, c));
    let max_gap = |run: &[(f64, f64)]| {
        let mut gaps: Vec<f64> = run.windows(2).map(|w| w[1].0 - w[0].0).collect();
        gaps.sort_by(f64::total_cmp);
        5.0 * gaps.get(gaps.len() / 2).copied().unwrap_or(TAU)
    };
    let (gap_a, gap_b) = (max_gap(&a), max_gap(&b));
    let mut best = (0.0_f64, 0.0_f64);
    for (theta, r) in &a {
        if let Some(rb) = radius_at(&b, *theta, gap_b) {
            if (r - rb).abs() > best.0 {
                best = ((r - rb).abs(), *theta);
            }
        }
    }
    for (theta, r) in &b {
        if let Some(ra) = radius_at(&a, *theta, gap_a) {
            if (r - ra).abs() > best.0 {
                best = ((r - ra).abs(), *theta);
            }
        }
    }
    Ok(Hysteresis {
        h: best.0,
        at_angle_deg: best.1.to_degrees(),
        centre: c,
    })
}

#[cfg(test)]
mod tests;
