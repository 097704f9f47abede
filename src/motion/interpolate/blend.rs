//! The blend arc of one corner under G64 P, as LinuxCNC's trajectory planner builds it
//! between two straight lines (R. Ellenberg's circular blends, LinuxCNC 2.7+:
//! `src/emc/tp/blendmath.c` `blendComputeParameters`, `blendFindPoints3`; `tc.c`
//! `tcFindBlendTolerance`): a circular arc tangent to both lines whose midpoint lies within
//! the tolerance of the programmed corner, as large as the tolerance, the lines' lengths and
//! the speed it is planned for allow.
//!
//! With `θ` half the angle between the two lines (`θ = acos(−u₁·u₂)/2`; `φ = π − 2θ` the turn):
//!
//! 1. tolerance `T = min(P, L₁/4, L₂/4)` (`tcFindBlendTolerance`, ratio 0.25 of each
//!    segment's nominal length);
//! 2. the arc may reach `d_tol = cos θ · T / (1 − sin θ)` along each line from the corner (its
//!    midpoint is then exactly `T` from the corner), and at most half of each line
//!    (`BLEND_DIST_FRACTION` 0.5): `d_geom = min(d_tol, L₁/2 (what is left of it), L₂/2)`,
//!    `R_geom = tan θ · d_geom`;
//! 3. its speed `v_plan = min(v_R(R_geom), v_goal)` (`v_goal` the larger feed of the two),
//!    where `v_R(R) = min(√(a_n R), ∛(j_n R²))` is the speed a radius `R` allows (normal
//!    acceleration `v²/R ≤ a_n`, and its rate `v³/R² ≤ j_n`, LinuxCNC's S-curve planner's
//!    `R_jerk_min = v^{3/2}/√j`);
//! 4. its radius only as large as that speed needs, or the equivalent parabolic blend takes:
//!    `R = max(v_plan²/a_n, √(v_plan³/j_n), min(s_blend/φ, R_geom))` with `a_p = a_max/2`,
//!    `t_blend = min(√(2 a_p d_geom), v_plan)/a_p`, `s_blend = t_blend · v_plan`;
//! 5. the arc starts and ends `d = R / tan θ` from the corner along each line.
//!
//! `a_max` and `j_max` are the smallest acceleration and jerk caps of the plane's two axes
//! (LinuxCNC's inscribed circle of the axes' bounds, exact for a principal plane). Where
//! LinuxCNC takes the normal acceleration as `√3/2 · a_max`, this takes the share the
//! interpolator gives curvature on any arc, `a_n = a_max/2` and `j_n = j_max/2`
//! (`super::segment`), so the arc is sized for the speed the interpolator will run it at. Blends are made for two straight feed (or two rapid)
//! moves of the program frame (RTCP off, rotary axes still) whose plane is XY, ZX or YZ; any
//! other corner keeps the look-ahead's corner rule (LinuxCNC also blends lines with arcs,
//! and corners in any plane).

use crate::motion::gcode::{Feed, Motion, Plane};
use crate::motion::machine::Machine;

/// LinuxCNC's share of a segment's length a blend may take (`BLEND_DIST_FRACTION`).
const BLEND_DIST_FRACTION: f64 = 0.5;
/// LinuxCNC's largest tolerance as a share of each segment's length (`tcFindBlendTolerance`).
const TOLERANCE_RATIO: f64 = 0.25;
/// Share of the axes' acceleration and jerk given to the arc's curvature: the interpolator's
/// own on arcs (`super::segment`'s `share`), so the arc runs at the speed it was sized for.
const NORMAL_SHARE: f64 = 0.5;
/// Smallest blend arc kept, mm (LinuxCNC refuses arcs shorter than `TP_MIN_ARC_LENGTH`).
const MIN_ARC_MM: f64 = 1e-6;
/// Smallest turn blended, rad: below it the lines are collinear (LinuxCNC's
/// `TP_ANGLE_EPSILON` 1e-6 on the half angle's distance from π/2).
const MIN_TURN_RAD: f64 = 2e-6;
/// Largest turn blended, rad: a reversal has no tangent arc within any tolerance.
const MAX_TURN_RAD: f64 = std::f64::consts::PI - 2e-6;

/// The two straight moves meeting at a corner (program frame, mm).
pub(super) struct CornerLines {
    /// The corner point.
    pub corner: [f64; 3],
    /// Unit direction of the incoming line.
    pub u1: [f64; 3],
    /// Unit direction of the outgoing line.
    pub u2: [f64; 3],
    /// What is left of the incoming line (a blend at its start may have taken some), mm.
    pub len1_left: f64,
    /// Programmed lengths of the incoming and outgoing lines, mm.
    pub len1: f64,
    pub len2: f64,
    /// Their feeds (both rapid or both per minute).
    pub feed1: Feed,
    pub feed2: Feed,
}

/// A blend arc: where it leaves the first line and joins the second, its motion and feed.
pub(super) struct BlendArc {
    /// Start (on the incoming line) and end (on the outgoing line), mm.
    pub start: [f64; 3],
    pub end: [f64; 3],
    /// The arc (plane, centre, signed sweep).
    pub motion: Motion,
    /// The larger of the two lines' feeds (LinuxCNC's `v_req`).
    pub feed: Feed,
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The plane whose normal is the coordinate axis `normal` (0 X, 1 Y, 2 Z).
fn plane_of(normal: usize) -> Plane {
    match normal {
        0 => Plane::Yz,
        1 => Plane::Zx,
        _ => Plane::Xy,
    }
}

/// The blend arc of `c` within `tolerance_mm` on `machine` (see the module docs), or None
/// when the corner is not blended: collinear, a reversal, not in a principal plane, or an
/// arc too short to keep.
pub(super) fn blend_arc(c: &CornerLines, tolerance_mm: f64, machine: &Machine) -> Option<BlendArc> {
    let turn = dot(&c.u1, &c.u2).clamp(-1.0, 1.0).acos();
    if !(MIN_TURN_RAD..=MAX_TURN_RAD).contains(&turn) {
        return None;
    }
    let n = cross(&c.u1, &c.u2);
    let n_len = dot(&n, &n).sqrt();
    let normal = (0..3).max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs()))?;
    if (0..3).any(|i| i != normal && n[i].abs() > 1e-9 * n_len) {
        return None;
    }
    let plane = plane_of(normal);
    let (p0, p1, _) = plane.axes();
    let lim = |i: usize| machine.axes[i].limits;
    let a_max = lim(p0).max_accel.min(lim(p1).max_accel);
    let j_max = lim(p0).max_jerk.min(lim(p1).max_jerk);
    let v_axes = lim(p0).max_vel.min(lim(p1).max_vel);
    let speed = |f: Feed| match f {
        Feed::PerMinute(f) => f / 60.0,
        _ => machine.rapid_mm_min / 60.0,
    };
    let v_goal = speed(c.feed1).max(speed(c.feed2)).min(v_axes);
    let theta = 0.5 * (std::f64::consts::PI - turn);
    let tol = tolerance_mm
        .min(TOLERANCE_RATIO * c.len1)
        .min(TOLERANCE_RATIO * c.len2);
    let d_tol = theta.cos() * tol / (1.0 - theta.sin());
    let d_geom = d_tol
        .min(c.len1_left.min(BLEND_DIST_FRACTION * c.len1))
        .min(BLEND_DIST_FRACTION * c.len2);
    let r_geom = theta.tan() * d_geom;
    let (a_n, j_n) = (NORMAL_SHARE * a_max, NORMAL_SHARE * j_max);
    let v_radius = (a_n * r_geom).sqrt().min((j_n * r_geom * r_geom).cbrt());
    let v_plan = v_radius.min(v_goal);
    let a_p = 0.5 * a_max;
    let t_blend = (2.0 * a_p * d_geom).sqrt().min(v_plan) / a_p;
    let r_blend = (t_blend * v_plan / turn).min(r_geom);
    let r_speed = (v_plan * v_plan / a_n).max((v_plan.powi(3) / j_n).sqrt());
    let radius = r_speed.max(r_blend).min(r_geom);
    if radius.is_nan() || radius * turn < MIN_ARC_MM {
        return None;
    }
    let d = radius / theta.tan();
    let start: [f64; 3] = std::array::from_fn(|i| c.corner[i] - d * c.u1[i]);
    let end: [f64; 3] = std::array::from_fn(|i| c.corner[i] + d * c.u2[i]);
    let bis: [f64; 3] = std::array::from_fn(|i| c.u2[i] - c.u1[i]);
    let bis_len = dot(&bis, &bis).sqrt();
    let to_centre = radius / theta.sin() / bis_len;
    let center: [f64; 3] = std::array::from_fn(|i| c.corner[i] + to_centre * bis[i]);
    let sweep_rad = turn.copysign(n[normal]);
    let feed = match (c.feed1, c.feed2) {
        (Feed::PerMinute(a), Feed::PerMinute(b)) => Feed::PerMinute(a.max(b)),
        _ => Feed::Rapid,
    };
    Some(BlendArc {
        start,
        end,
        motion: Motion::Arc {
            plane,
            center,
            sweep_rad,
        },
        feed,
    })
}

#[cfg(test)]
mod tests;
