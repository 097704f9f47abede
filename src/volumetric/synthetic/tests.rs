//! Unit tests of `crate::volumetric::synthetic`.

use super::*;

#[test]
fn magnitudes_follow_the_issue() {
    let m = SyntheticMachine::new(7, ShapeFamily::TrendAndWaviness);
    for axis in 0..3 {
        for f in 0..6 {
            let v: Vec<f64> = (0..=100)
                .map(|i| m.motion(axis, f, m.travel_mm[axis] * i as f64 / 100.0))
                .collect();
            let pp = v.iter().cloned().fold(f64::MIN, f64::max)
                - v.iter().cloned().fold(f64::MAX, f64::min);
            let (lo, hi) = if f == axis {
                (5e-3, 30e-3)
            } else if f < 3 {
                (2e-3, 15e-3)
            } else {
                (5e-6, 40e-6)
            };
            assert!(
                pp >= lo * 0.98 && pp <= hi * 1.02,
                "axis {axis} f {f}: {pp}"
            );
        }
    }
    assert!(
        m.squareness_rad
            .iter()
            .all(|s| (10e-6..=60e-6).contains(&s.abs()))
    );
    // the total error is tens of µm, as on real machines
    let e = m.error([800.0, 500.0, 400.0]);
    let len = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
    assert!(len > 5e-3 && len < 0.2, "{len}");
}
