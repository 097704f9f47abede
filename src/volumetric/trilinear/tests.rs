//! Unit tests of `crate::volumetric::trilinear`.

use super::*;

fn data_from(f: impl Fn([f64; 3]) -> [f64; 3], n: [usize; 3]) -> VolumetricData {
    let mut d = VolumetricData {
        nodes: vec![],
        errors: vec![],
    };
    for iz in 0..n[2] {
        for iy in 0..n[1] {
            for ix in 0..n[0] {
                let p = [ix as f64 * 100.0, iy as f64 * 50.0, iz as f64 * 40.0];
                d.nodes.push(p);
                d.errors.push(f(p));
            }
        }
    }
    d
}

#[test]
fn reproduces_nodes_and_trilinear_fields_exactly() {
    let f = |p: [f64; 3]| {
        [
            1e-3 + 2e-5 * p[0] - 1e-5 * p[1] * p[2] * 1e-2,
            3e-6 * p[0] * p[1] * 1e-2,
            -4e-5 * p[2],
        ]
    };
    let d = data_from(f, [4, 3, 3]);
    let m = TrilinearMap::fit(&d, None).unwrap();
    for (p, e) in d.nodes.iter().zip(&d.errors) {
        let q = m.eval(*p);
        (0..3).for_each(|j| assert!((q[j] - e[j]).abs() < 1e-15));
    }
    let p = [123.0, 77.0, 51.0];
    let (q, e) = (m.eval(p), f(p));
    (0..3).for_each(|j| assert!((q[j] - e[j]).abs() < 1e-12, "{q:?} {e:?}"));
    // off the box: edge value held
    let out = m.eval([1e4, -50.0, 40.0]);
    let edge = f([300.0, 0.0, 40.0]);
    (0..3).for_each(|j| assert!((out[j] - edge[j]).abs() < 1e-12));
    assert_eq!(m.parameter_count(), 3 * 36 + 10);
}

#[test]
fn curvature_between_nodes_is_missed_and_limit_resamples() {
    let f = |p: [f64; 3]| [1e-8 * p[0] * p[0], 0.0, 0.0];
    let d = data_from(f, [5, 2, 2]);
    let m = TrilinearMap::fit(&d, None).unwrap();
    // midway between nodes 100 apart the chord overshoots by h²/4·a = 2.5e-5
    let q = m.eval([150.0, 0.0, 0.0]);
    assert!((q[0] - f([150.0, 0.0, 0.0])[0] - 2.5e-5).abs() < 1e-12);
    let lim = TrilinearMap::fit(&d, Some(3)).unwrap();
    assert_eq!(lim.levels[0], vec![0.0, 200.0, 400.0]);
    assert_eq!(lim.values.len(), 3 * 2 * 2);
    assert!(TrilinearMap::fit(&d, Some(1)).is_err());
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig {
        cases: 64,
        rng_seed: proptest::test_runner::RngSeed::Fixed(7),
        failure_persistence: None,
        ..Default::default()
    })]
    /// Laws: affine fields are reproduced everywhere; values stay within the corners' range.
    #[test]
    fn affine_exact_and_bounded(
        a in proptest::array::uniform4(-1e-2f64..1e-2),
        vals in proptest::collection::vec(-1e-2f64..1e-2, 27),
        q in proptest::array::uniform3(0.0f64..1.0),
    ) {
        let affine = |p: [f64; 3]| [a[0] + 1e-5 * (a[1] * p[0] + a[2] * p[1] + a[3] * p[2]), 0.0, 0.0];
        let m = TrilinearMap::fit(&data_from(affine, [3, 3, 3]), None).unwrap();
        let p = [q[0] * 200.0, q[1] * 100.0, q[2] * 80.0];
        proptest::prop_assert!((m.eval(p)[0] - affine(p)[0]).abs() < 1e-12);
        let table = TrilinearMap { levels: m.levels.clone(), values: vals.iter().map(|&v| [v, -v, 0.0]).collect() };
        let v = table.eval(p)[0];
        let (lo, hi) = vals.iter().fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
        proptest::prop_assert!(v >= lo - 1e-15 && v <= hi + 1e-15);
    }
}
