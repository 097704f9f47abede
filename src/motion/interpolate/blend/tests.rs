//! Unit tests of `crate::motion::interpolate::blend`: the blend arc's geometry against its
//! definition (tangent to both lines, its midpoint `T` from the corner) and the corners it
//! leaves alone.

use super::*;
use crate::motion::gcode::{Block, Pose};
use serde_json::json;

fn machine() -> Machine {
    let ax = json!({"kv": 30});
    Machine::from_json(&json!({"kinematics": "xyz", "axes": {"X": ax, "Y": ax, "Z": ax}})).unwrap()
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = dot(&v, &v).sqrt();
    v.map(|x| x / n)
}

/// A corner at the origin between lines of lengths `len1`, `len2` along `u1`, `u2` at F.
fn corner(u1: [f64; 3], u2: [f64; 3], len1: f64, len2: f64, f_mm_min: f64) -> CornerLines {
    CornerLines {
        corner: [0.0; 3],
        u1: unit(u1),
        u2: unit(u2),
        len1_left: len1,
        len1,
        len2,
        feed1: Feed::PerMinute(f_mm_min),
        feed2: Feed::PerMinute(f_mm_min),
    }
}

/// The arc as a block, to evaluate it with the interpolator's own geometry.
fn as_block(arc: &BlendArc) -> Block {
    let at = |xyz| Pose {
        xyz,
        a: 0.0,
        c: 0.0,
    };
    Block {
        line: 1,
        motion: arc.motion,
        start: at(arc.start),
        end: at(arc.end),
        feed: arc.feed,
        rtcp: false,
    }
}

fn norm(v: [f64; 3]) -> f64 {
    dot(&v, &v).sqrt()
}

/// At high feed on long lines the tolerance binds: the arc's midpoint lies exactly `P` from
/// the corner (LinuxCNC's `h − R = T`), it leaves and joins the lines tangentially, at the
/// same distance `d` from the corner on both, for turns of 30° to 150° in all three planes.
#[test]
fn the_tolerance_bounds_the_arc_midpoint_and_the_arc_is_tangent() {
    let m = machine();
    for (u1, u2s) in [
        (
            [1.0, 0.0, 0.0],
            [
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
                [-1.0, 0.4, 0.0],
                [0.3, -1.0, 0.0],
            ],
        ),
        (
            [0.0, 0.0, -1.0],
            [
                [1.0, 0.0, 0.0],
                [1.0, 0.0, -2.0],
                [-1.0, 0.0, 1.0],
                [0.0, 0.0, 0.0],
            ],
        ),
        (
            [0.0, 1.0, 0.0],
            [
                [0.0, 0.0, 1.0],
                [0.0, -0.5, -1.0],
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0],
            ],
        ),
    ] {
        for u2 in u2s.into_iter().filter(|u| norm(*u) > 0.0) {
            let c = corner(u1, u2, 100.0, 100.0, 60_000.0);
            let arc = blend_arc(&c, 0.05, &m).expect("a blendable corner");
            let b = as_block(&arc);
            let mid = b.pose_at(0.5).xyz;
            assert!(
                (norm(mid) - 0.05).abs() < 1e-9,
                "midpoint {} from the corner",
                norm(mid)
            );
            let (d1, d2) = (norm(arc.start), norm(arc.end));
            assert!((d1 - d2).abs() < 1e-12);
            for i in 0..3 {
                assert!(
                    (arc.start[i] + d1 * c.u1[i]).abs() < 1e-12,
                    "start on line 1"
                );
                assert!((arc.end[i] - d2 * c.u2[i]).abs() < 1e-12, "end on line 2");
            }
            let h = 1e-7;
            let t0 = b.pose_at(h).xyz.map(|x| x / h);
            let t1 = b.pose_at(1.0 - h).xyz;
            let t0 = unit(std::array::from_fn(|i| t0[i] - arc.start[i] / h));
            let t1 = unit(std::array::from_fn(|i| arc.end[i] - t1[i]));
            assert!(dot(&t0, &c.u1) > 1.0 - 1e-9, "tangent at the start");
            assert!(dot(&t1, &c.u2) > 1.0 - 1e-9, "tangent at the end");
        }
    }
}

/// Short lines: the tolerance is cut to a quarter of the shorter line and the arc takes at
/// most half of each (LinuxCNC `tcFindBlendTolerance`, `BLEND_DIST_FRACTION`); a slow feed
/// needs a smaller arc (its radius only as large as the speed needs).
#[test]
fn line_lengths_and_feed_shrink_the_arc() {
    let m = machine();
    let c = corner([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.4, 1.0, 60_000.0);
    let arc = blend_arc(&c, 1.0, &m).unwrap();
    let mid = as_block(&arc).pose_at(0.5).xyz;
    assert!(
        norm(mid) <= 0.25 * 0.4 + 1e-12,
        "tolerance cut to L/4: {}",
        norm(mid)
    );
    assert!(norm(arc.start) <= 0.5 * 0.4 + 1e-12);
    let fast = blend_arc(
        &corner([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 100.0, 100.0, 60_000.0),
        0.5,
        &m,
    )
    .unwrap();
    let slow = blend_arc(
        &corner([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 100.0, 100.0, 60.0),
        0.5,
        &m,
    )
    .unwrap();
    assert!(
        norm(slow.start) < 0.5 * norm(fast.start),
        "{} vs {}",
        norm(slow.start),
        norm(fast.start)
    );
}

#[test]
fn collinear_reversed_and_skew_corners_are_not_blended() {
    let m = machine();
    let x = [1.0, 0.0, 0.0];
    assert!(blend_arc(&corner(x, x, 10.0, 10.0, 600.0), 0.05, &m).is_none());
    assert!(blend_arc(&corner(x, [-1.0, 0.0, 0.0], 10.0, 10.0, 600.0), 0.05, &m).is_none());
    // A corner whose plane is none of XY, ZX, YZ keeps the look-ahead's corner rule.
    assert!(blend_arc(&corner(x, [0.0, 1.0, 1.0], 10.0, 10.0, 600.0), 0.05, &m).is_none());
}
