//! Unit tests of `crate::cam::predistort::loops`.

use super::*;

/// A loop at the corner `c` = (2, 0) starts after `c − a·d_in` (that point is the last kept
/// one) and ends at `c + b·d_out`, with chords of [`LOOP_STEP_MM`] on average (longer near the ends, where the
/// curve leaves its end points fastest: at most three times that here), and goes beyond the
/// corner along `d_in`, less far than its control point `C1`.
#[test]
fn loop_geometry() {
    let (d_in, d_out) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let p = [0.5, 0.6, 0.3, 0.0, 0.0, 0.0];
    let pts = loop_points(
        ([1.5, 0.0, 0.0], d_in),
        ([2.0, 0.6, 0.0], d_out),
        d_in,
        d_out,
        &p,
    );
    let last = *pts.last().unwrap();
    assert!(norm(sub(last, [2.0, 0.6, 0.0])) < 1e-12, "{last:?}");
    let mut prev = [1.5, 0.0, 0.0];
    let mut reach = f64::NEG_INFINITY;
    let (mut sum, mut longest) = (0.0, 0.0f64);
    for q in &pts {
        let chord = norm(sub(*q, prev));
        sum += chord;
        longest = longest.max(chord);
        reach = reach.max(q[0] - 2.0);
        prev = *q;
    }
    let mean = sum / pts.len() as f64;
    println!(
        "{} points, chords {mean:.4} mm on average, {longest:.4} mm at most",
        pts.len()
    );
    assert!(mean <= LOOP_STEP_MM + 1e-9, "mean chord {mean}");
    assert!(longest <= 3.0 * LOOP_STEP_MM, "longest chord {longest}");
    assert!(
        reach > 0.0 && reach < 0.3,
        "beyond the corner by {reach} mm"
    );
    // The smooth length on either side of the corner, up to the next turn of more than
    // SMOOTH_TURN_DEG between two chords.
    let path = [
        [0.5, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 1.5, 0.0],
        [2.5, 1.6, 0.0],
    ];
    let free = |_: usize| false;
    let start = [0.0; 3];
    assert!((smooth_extent(&path, start, 2, true, &free) - 2.0).abs() < 1e-12);
    assert!((smooth_extent(&path, start, 2, false, &free) - 1.5).abs() < 1e-12);
    let kept = |j: usize| j == 0;
    assert!((smooth_extent(&path, start, 2, true, &kept) - 1.0).abs() < 1e-12);
}

/// On an arc (chords turning by 5° each) the smooth stretch runs on to the arc's end, where
/// the path turns by 15°; a loop's end point and tangent there are the path's own.
#[test]
fn loops_reach_along_arcs() {
    let r = 10.0;
    let on = |deg: f64| {
        let t = deg.to_radians();
        [r * t.cos(), r * t.sin(), 0.0]
    };
    // From the corner at 0°, chords of 5° up to 45°, then a turn of 15° more.
    let mut path: Vec<[f64; 3]> = (0..=9).map(|k| on(5.0 * f64::from(k))).collect();
    let end = *path.last().unwrap();
    let (u, v) = (
        (135.0f64 + 20.0).to_radians().cos(),
        (135.0f64 + 20.0).to_radians().sin(),
    );
    path.push([end[0] + u, end[1] + v, 0.0]);
    let chord = 2.0 * r * (2.5f64.to_radians()).sin();
    let free = |_: usize| false;
    let reach = smooth_extent(&path, [r, -1.0, 0.0], 0, false, &free);
    assert!(
        (reach - 9.0 * chord).abs() < 1e-9,
        "{reach} vs {}",
        9.0 * chord
    );
}

/// Stage 5's offsets: around a 90° corner at (2, 0) with points every 20 µm, each moving
/// point's direction is the normal to the path in the corner's plane, the offset fades to zero
/// at the window's ends (lo..hi = 1..3 mm of path), equals the coefficients where they are
/// all equal (the B-splines sum to one between the end knots) and leaves the points outside
/// the window and the still ones where they are.
#[test]
fn lateral_offsets_are_smooth_normals_within_the_window() {
    let mut pts = Vec::new();
    for i in 0..=100 {
        pts.push([0.02 * f64::from(i), 0.0, 0.0]);
    }
    for i in 1..=100 {
        pts.push([2.0, 0.02 * f64::from(i), 0.0]);
    }
    let sigma: Vec<f64> = (0..pts.len()).map(|k| 0.02 * k as f64).collect();
    let spot = crate::cam::predistort::tests::right_angle_spot(100, 2.0, (1.0, 3.0), 0.5);
    let still = |k: usize| k == 120;
    let wins = lateral::windows(&pts, &sigma, std::slice::from_ref(&spot), &still);
    let w = &wins[0];
    assert!(w.knots >= 10, "{} knots", w.knots);
    assert!(!w.points.contains(&120) && w.points.contains(&90) && !w.points.contains(&40));
    for (i, &k) in w.points.iter().enumerate() {
        let n = w.normals[i];
        let a = pts[k - 1];
        let b = pts[k + 1];
        let t = sub(b, a);
        let dot = n[0] * t[0] + n[1] * t[1] + n[2] * t[2];
        assert!(dot.abs() < 1e-9 && n[2] == 0.0 && (norm(n) - 1.0).abs() < 1e-12);
    }
    let at = |k: usize| {
        w.weights[w.points.iter().position(|&j| j == k).unwrap()]
            .iter()
            .sum::<f64>()
    };
    assert!(at(50) < 1e-12 && at(150) < 1e-12, "{} {}", at(50), at(150));
    assert!((at(80) - 1.0).abs() < 1e-9, "{}", at(80));
    let theta = vec![vec![0.01; w.knots]];
    let moved = lateral::apply(&pts, &wins, &theta);
    assert!((norm(sub(moved[80], pts[80])) - 0.01).abs() < 1e-4);
    for k in [0, 40, 120, 170, 200] {
        assert_eq!(moved[k], pts[k], "point {k}");
    }
}
