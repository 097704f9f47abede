//! Unit tests of `crate::motion::kinematics`.

use super::*;
use proptest::prelude::*;

fn machine() -> Kinematics {
    Kinematics::XyzacTable(TableGeometry {
        a_axis_origin: [0.0, 12.5, -80.0],
        c_axis_origin: [3.0, -4.0, -60.0],
        tool_length: 120.0,
    })
}

#[test]
fn zero_angles_only_shift_by_tool_length() {
    let k = machine();
    let q = k.inverse(&[10.0, 20.0, 30.0], 0.0, 0.0);
    assert!((q[0] - 10.0).abs() < 1e-12 && (q[1] - 20.0).abs() < 1e-12);
    assert!((q[2] - 150.0).abs() < 1e-12);
}

#[test]
fn a90_tilts_tool_axis_to_workpiece_y() {
    // A = +90°: the table turns so that the tool (machine +Z) points along workpiece +Y.
    let t = machine().forward(&[0.0, 0.0, 0.0, 90.0, 0.0]);
    assert!((t.axis[1] - 1.0).abs() < 1e-12, "{:?}", t.axis);
    let (a, c) = orientation_to_ac(&t.axis);
    assert!((a - 90.0).abs() < 1e-9 && c.abs() < 1e-9);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]
    #[test]
    fn forward_after_inverse_is_identity(
        x in -500.0..500.0f64, y in -500.0..500.0f64, z in -300.0..300.0f64,
        a in -120.0..120.0f64, c in -720.0..720.0f64,
    ) {
        let k = machine();
        let q = k.inverse(&[x, y, z], a, c);
        let t = k.forward(&q);
        prop_assert!(gcode_dist(&t.tip, &[x, y, z]) < 1e-9);
        // Tool axis from the angles matches the closed form of eq. 1.
        let (sa, ca) = a.to_radians().sin_cos();
        let (sc, cc) = c.to_radians().sin_cos();
        let expect = [sa * sc, sa * cc, ca];
        prop_assert!(gcode_dist(&t.axis, &expect) < 1e-12);
        // And back: inverse(forward(q)) = q.
        let q2 = k.inverse(&t.tip, q[3], q[4]);
        for i in 0..5 { prop_assert!((q2[i] - q[i]).abs() < 1e-9); }
        // Orientation → angles → orientation.
        if a.abs() > 1e-3 {
            let (a2, c2) = orientation_to_ac(&t.axis);
            let back = k.forward(&[0.0, 0.0, 0.0, a2, c2]).axis;
            prop_assert!(gcode_dist(&back, &t.axis) < 1e-9);
        }
    }
}

fn gcode_dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    crate::motion::program::dist3(a, b)
}
