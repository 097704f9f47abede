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

/// A convex arc of radius 40 mm sampled at `m` points, its CL points at R along the normals,
/// turned by `a` about z, shifted by `t`, every length times `k`.
fn arc_segment(m: usize, r: f64, a: f64, t: [f64; 3], k: f64) -> ([[f64; 3]; 2], Vec<[f64; 3]>) {
    let rho = 40.0;
    let place = |p: [f64; 3]| {
        let q = rot_z(p, a);
        [k * q[0] + t[0], k * q[1] + t[1], k * q[2] + t[2]]
    };
    let pt = |phi: f64| {
        (
            [rho * phi.sin(), 0.0, rho * phi.cos()],
            [phi.sin(), 0.0, phi.cos()],
        )
    };
    let (p0, n0) = pt(-0.02);
    let (p1, n1) = pt(0.03);
    let cc: Vec<[f64; 3]> = (0..m)
        .map(|i| place(pt(-0.02 + 0.05 * i as f64 / (m - 1) as f64).0))
        .collect();
    let cl = [place(add3(p0, scale(n0, r))), place(add3(p1, scale(n1, r)))];
    (cl, cc)
}

#[test]
fn the_profile_is_the_same_under_rigid_motion_and_scaling() {
    let f = StepFeatures::profile();
    let mut sp = CubicSpline3::new();
    let row = |cl, cc: &[[f64; 3]], r: f64, sp: &mut CubicSpline3| {
        let mut out = vec![0.0; f.len()];
        let info = f.write(r, cl, cc, sp, &mut out).unwrap();
        (out, info)
    };
    let (cl, cc) = arc_segment(20, 5.0, 0.0, [0.0; 3], 1.0);
    let (a, ia) = row(cl, &cc, 5.0, &mut sp);
    assert!(ia.convex);
    // The arc's chord error: 40 + 5 = 45 mm offset radius, chord 2.25 mm -> ~14 µm.
    assert!((ia.scale_um - 14.06).abs() < 0.2, "{}", ia.scale_um);
    let (cl2, cc2) = arc_segment(20, 5.0, 2.1, [-120.0, 33.0, 57.0], 1.0);
    let (b, ib) = row(cl2, &cc2, 5.0, &mut sp);
    let (cl3, cc3) = arc_segment(20, 5.0, 0.4, [5.0, 6.0, 7.0], 2.0);
    let (c, ic) = row(cl3, &cc3, 10.0, &mut sp);
    for (v, w) in [(&b, &ib), (&c, &ic)] {
        let diff = a
            .iter()
            .zip(v.iter())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-6, "max diff {diff}");
        assert_eq!(w.convex, ia.convex);
    }
    assert!((ib.scale_um / ia.scale_um - 1.0).abs() < 1e-6);
    assert!((ic.scale_um / ia.scale_um - 2.0).abs() < 1e-6);
    // 31 points on the same arc: the same 20-point profile (the spline is resampled).
    let (cl4, cc4) = arc_segment(31, 5.0, 0.0, [0.0; 3], 1.0);
    let (d, _) = row(cl4, &cc4, 5.0, &mut sp);
    let diff = a
        .iter()
        .zip(&d)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(diff < 1e-4, "resampled: {diff}");
}

#[test]
fn profile_targets_combine_back_to_the_exact_error() {
    let f = StepFeatures::profile();
    let mut sp = CubicSpline3::new();
    let mut solver = crate::geometry::StepErrorSolver::default().both_branches(true);
    for m in [11, 20, 31] {
        let (cl, cc) = arc_segment(m, 6.0, 0.3, [1.0, 2.0, 3.0], 1.0);
        let e = solver.solve(6.0, cl, &cc).unwrap();
        let mut row = vec![0.0; f.len()];
        let info = f.write(6.0, cl, &cc, &mut sp, &mut row).unwrap();
        assert_eq!(info.convex, e.convex);
        let t = f.targets(&e, &info);
        // The continuous curve reaches at least the samples' extremes.
        assert!(t.iter().all(|v| *v >= -1e-9), "{t:?}");
        // ... and no more than the bound the outputs are clipped to.
        assert!(t[0] <= info.miss_bound_um / info.scale_um, "{t:?} {info:?}");
        let back = f.combine(&t, &[info])[0];
        assert!(
            (back - e.error_mm * 1e3).abs() < 1e-9,
            "{back} vs {}",
            e.error_mm * 1e3
        );
        // The samples alone miss a little (what the network learns).
        let knot = StepFeatures::knot_estimate(&[info])[0];
        assert!(knot <= e.error_mm * 1e3 + 1e-9);
    }
}
