//! Unit tests of the physical ranges and of the pairing of measured points.

use super::*;

/// A flat nu × nv grid at 2 mm spacing, normals +z.
fn grid(nu: usize, nv: usize) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let pts = (0..nu * nv)
        .map(|k| [2.0 * (k % nu) as f64, 2.0 * (k / nu) as f64, 0.0])
        .collect();
    (pts, vec![[0.0, 0.0, 1.0]; nu * nv])
}

#[test]
fn points_on_their_nominals_give_their_normal_deviations() {
    let (q, n) = grid(4, 3);
    let m: Vec<[f64; 3]> = q.iter().map(|p| [p[0] + 0.01, p[1], p[2] + 0.2]).collect();
    let d = Limits::default().pair_points(&m, &q, &n, 4).unwrap();
    assert!(d.iter().all(|v| (v - 0.2).abs() < 1e-12));
}

#[test]
fn reversed_points_are_refused_and_called_reversed() {
    let (q, n) = grid(4, 3);
    let mut m = q.clone();
    m.reverse();
    let e = Limits::default().pair_points(&m, &q, &n, 4).unwrap_err();
    assert_eq!(e.status().as_u16(), 422);
    assert!(e.detail().contains("points[0]"), "{}", e.detail());
    assert!(e.detail().contains("reverse"), "{}", e.detail());
}

#[test]
fn shifted_points_are_refused_and_called_shifted() {
    let (q, n) = grid(5, 4);
    let mut m: Vec<[f64; 3]> = q[1..].to_vec();
    m.push([8.0, 8.0, 0.0]);
    let e = Limits::default().pair_points(&m, &q, &n, 5).unwrap_err();
    assert!(
        e.detail().contains("shifted by one point"),
        "{}",
        e.detail()
    );
    let mut m: Vec<[f64; 3]> = q[..q.len() - 5].to_vec();
    m.splice(0..0, (0..5).map(|i| [2.0 * i as f64, -2.0, 0.0]));
    let e = Limits::default().pair_points(&m, &q, &n, 5).unwrap_err();
    assert!(e.detail().contains("shifted by one row"), "{}", e.detail());
}

#[test]
fn the_tolerance_is_the_setting_or_half_the_spacing() {
    let (q, _) = grid(3, 3);
    let t = tolerances(&q, 3, 0.5);
    assert!(t.iter().all(|&v| v == 0.5));
    let t = tolerances(&q, 3, 5.0);
    assert!(t.iter().all(|&v| v == 1.0));
    assert_eq!(tolerances(&q[..1], 1, 0.5), vec![0.5]);
}

#[test]
fn deviations_beyond_the_setting_are_refused_naming_it() {
    let l = Limits::default();
    assert!(l.check_deviations("deviations", &[0.1, -4.9]).is_ok());
    let e = l.check_deviations("deviations", &[0.1, 1e308]).unwrap_err();
    assert_eq!(e.status().as_u16(), 400);
    assert!(e.detail().contains("deviations[1]"));
    assert!(e.detail().contains("--max-deviation-mm"));
    let (q, n) = grid(2, 2);
    let m: Vec<[f64; 3]> = q.iter().map(|p| [p[0], p[1], 7.0]).collect();
    assert_eq!(
        l.pair_points(&m, &q, &n, 2).unwrap_err().status().as_u16(),
        400
    );
}

#[test]
fn coordinates_radii_and_volumetric_errors_have_ranges() {
    assert!(check_coords("p", &[[1.0, 2.0, 99_999.0]]).is_ok());
    assert!(check_coords("p", &[[1.0, 1e300, 0.0]]).is_err());
    assert!(check_tool_radius("tool_radius", 3.0).is_ok());
    for r in [-1.0, 0.0, 101.0, f64::NAN] {
        let e = check_tool_radius("tool_radius", r).unwrap_err();
        assert!(e.detail().contains("(0, 100]"), "{}", e.detail());
    }
    assert!(check_volumetric_errors("errors", &[[0.01, 0.0, -0.02]]).is_ok());
    assert!(check_volumetric_errors("errors", &[[0.0, 0.0, 15.0]]).is_err());
}
