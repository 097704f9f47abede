//! Unit tests of `crate::cli::demo`.

use super::*;

#[test]
fn saddle_normals_are_unit_and_orthogonal_to_the_surface() {
    let (p, n) = saddle();
    assert_eq!(p.len(), DEMO_N * DEMO_N);
    for nk in &n {
        let len = (nk[0].powi(2) + nk[1].powi(2) + nk[2].powi(2)).sqrt();
        assert!((len - 1.0).abs() < 1e-12);
        assert!(nk[2] > 0.0);
    }
    // Tangent along u at an interior point is orthogonal to the normal (finite difference).
    let k = 20 * DEMO_N + 25;
    let t = [
        p[k + 1][0] - p[k - 1][0],
        p[k + 1][1] - p[k - 1][1],
        p[k + 1][2] - p[k - 1][2],
    ];
    let dot = t[0] * n[k][0] + t[1] * n[k][1] + t[2] * n[k][2];
    assert!(dot.abs() < 1e-9, "{dot}");
}

#[test]
fn noise_is_bounded() {
    let mut s = 1;
    for _ in 0..10_000 {
        let v = noise(&mut s);
        assert!((-1.0..1.0).contains(&v));
    }
}

#[test]
fn demo_volumetric_map_has_the_iso_230_1_components() {
    let map = demo_volumetric_map().unwrap();
    let k = map
        .components
        .as_ref()
        .expect("a kinematic map has its components");
    let curves = crate::volumetric::component_curves(k, 11);
    assert_eq!(curves.axes.len(), 3);
    assert_eq!(curves.squareness.len(), 3);
    // The positioning error of each axis along itself is identified and not flat.
    for (axis, a) in curves.axes.iter().enumerate() {
        let v = a.curves[axis].values.as_ref().expect("identified");
        let range =
            v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min);
        assert!(range > 1.0, "axis {axis}: {range} um");
    }
}
