//! Unit tests of `crate::cam::predistort::loops`.

use super::*;

/// A loop starts after `c − a·d_in` (that point is the last kept one) and ends at
/// `c + b·d_out`, with chords of [`LOOP_STEP_MM`] on average (longer near the ends, where the
/// curve leaves its end points fastest: at most three times that here), and goes beyond the
/// corner along `d_in`, less far than its control point `C1`.
#[test]
fn loop_geometry() {
    let (c, d_in, d_out) = ([2.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let p = [0.5, 0.6, 0.3, 0.0, 0.0, 0.0];
    let pts = loop_points(c, d_in, d_out, &p);
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
    // The straight length on either side of the corner, up to a point off the line.
    let path = [
        [0.5, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 1.5, 0.0],
        [2.5, 1.6, 0.0],
    ];
    let free = |_: usize| false;
    let start = [0.0; 3];
    assert!((straight_extent(&path, start, 2, d_in, true, &free) - 2.0).abs() < 1e-12);
    assert!((straight_extent(&path, start, 2, d_out, false, &free) - 1.5).abs() < 1e-12);
    let kept = |j: usize| j == 0;
    assert!((straight_extent(&path, start, 2, d_in, true, &kept) - 1.0).abs() < 1e-12);
}
