//! Unit tests of `crate::geometry::step_features`.

use super::*;

fn rot_z(p: [f64; 3], a: f64) -> [f64; 3] {
    let (s, c) = a.sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]]
}

#[test]
fn local_features_ignore_rigid_motion_and_global_do_not() {
    let cc: Vec<[f64; 3]> = (0..20)
        .map(|i| {
            let x = i as f64 * 0.06;
            [x, 0.2 * x, 0.03 * x * x]
        })
        .collect();
    let n = [-0.05, 0.0, 1.0];
    let nn = normalize(n);
    let cl = [add3(cc[0], scale(nn, 5.0)), add3(cc[19], scale(nn, 5.0))];
    let mv = |p: [f64; 3]| {
        let q = rot_z(p, 0.7);
        [q[0] + 10.0, q[1] - 3.0, q[2] + 40.0]
    };
    let cc2: Vec<[f64; 3]> = cc.iter().map(|p| mv(*p)).collect();
    let cl2 = [mv(cl[0]), mv(cl[1])];
    let mut sp = CubicSpline3::new();
    for (f, same) in [
        (StepFeatures::local(), true),
        (StepFeatures::paper(), false),
    ] {
        let f = StepFeatures {
            knot_distances: true,
            ..f
        };
        let mut a = vec![0.0; f.len()];
        let mut b = vec![0.0; f.len()];
        f.write(5.0, cl, &cc, &mut sp, &mut a).unwrap();
        f.write(5.0, cl2, &cc2, &mut sp, &mut b).unwrap();
        let diff = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert_eq!(diff < 1e-9, same, "{:?}: max diff {diff}", f.frame);
    }
    // resampling: 39 points on the same curve give nearly the same 20-point row
    let dense: Vec<[f64; 3]> = (0..39)
        .map(|i| {
            let x = i as f64 * 0.06 * 19.0 / 38.0;
            [x, 0.2 * x, 0.03 * x * x]
        })
        .collect();
    let f = StepFeatures::local();
    let mut a = vec![0.0; f.len()];
    let mut b = vec![0.0; f.len()];
    f.write(5.0, cl, &cc, &mut sp, &mut a).unwrap();
    f.write(5.0, cl, &dense, &mut sp, &mut b).unwrap();
    assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9));
}

fn add3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
