//! Unit tests of `crate::motion::contour`.

use super::*;

#[test]
fn spline_through_circle_points_stays_on_circle() {
    let r = 10.0;
    let pts: Vec<[f64; 3]> = (0..=200)
        .map(|k| {
            let th = k as f64 * 0.01;
            [r * th.cos(), r * th.sin(), 0.0]
        })
        .collect();
    let s = PathSpline::new(pts, &[false; 201]);
    for j in 20..180 {
        let (p, _, _) = s.eval(j, s.h[j] * 0.5);
        let rad = (p[0] * p[0] + p[1] * p[1]).sqrt();
        // Chord sagitta would be r(1−cos(0.005)) = 1.25e-4 mm; the spline is far closer.
        assert!((rad - r).abs() < 1e-8, "segment {j}: {rad}");
    }
}

#[test]
fn offset_line_has_constant_contour_error() {
    // Command along X; actual lags along X and sits 0.01 mm off in Y.
    let n = 500;
    let cmd: Vec<Vec<f64>> = vec![
        (0..n).map(|i| i as f64 * 0.1).collect(),
        vec![0.0; n],
        vec![0.0; n],
    ];
    let act: Vec<Vec<f64>> = vec![
        (0..n).map(|i| (i as f64 * 0.1 - 0.5).max(0.0)).collect(),
        vec![0.01; n],
        vec![0.0; n],
    ];
    let rep = contour_error(&Kinematics::Xyz, &cmd, &act, &[]);
    for (i, e) in rep.contour_error.iter().enumerate() {
        assert!((e - 0.01).abs() < 1e-12, "{i}: {e}");
    }
    assert!((rep.tracking_max[0] - 0.5).abs() < 1e-12);
}

/// Oracle: on a path that never comes back near itself, the windowed search with skips
/// finds the same distance as projecting onto every spline segment.
#[test]
fn windowed_search_matches_brute_force() {
    let n = 3000;
    let x: Vec<f64> = (0..n)
        .map(|i| 0.02 * i as f64 + 0.00001 * (i as f64).powi(2))
        .collect();
    let y: Vec<f64> = x.iter().map(|v| 3.0 * (v / 4.0).sin()).collect();
    let z: Vec<f64> = x.iter().map(|v| 0.5 * (v / 7.0).cos()).collect();
    // Actual: a lagged (by 25 samples) and laterally disturbed copy.
    let lag = |c: &Vec<f64>, off: f64| -> Vec<f64> {
        (0..n)
            .map(|i: usize| c[i.saturating_sub(25)] + off * ((i as f64) * 0.05).sin())
            .collect()
    };
    let cmd = vec![x.clone(), y.clone(), z.clone()];
    let act = vec![lag(&x, 0.0), lag(&y, 0.03), lag(&z, 0.01)];
    let rep = contour_error(&Kinematics::Xyz, &cmd, &act, &[]);
    let pts: Vec<[f64; 3]> = (0..n).map(|i| [x[i], y[i], z[i]]).collect();
    let spline = PathSpline::new(pts.clone(), &vec![false; n]);
    for i in (0..n).step_by(7) {
        let a = [act[0][i], act[1][i], act[2][i]];
        let brute = (0..n - 1)
            .map(|j| {
                spline
                    .project(j, &a, chord_distance(&pts[j], &pts[j + 1], &a).1)
                    .0
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            (rep.contour_error[i] - brute).abs() < 1e-9,
            "{i}: {} vs {brute}",
            rep.contour_error[i]
        );
    }
    assert!(rep.max > 0.005);
}
