//! Unit tests of `crate::geometry::height_surface`.

use super::*;

#[test]
fn derivatives_match_finite_differences_and_constants_match_json() {
    let s = HeightSurface::reference(2).unwrap();
    assert!(s.validate().is_ok());
    // surfaces.json evaluates 2π/160 as 0.039269908169872414
    let HeightTerm::Sc(c) = s.terms[0] else {
        panic!()
    };
    assert_eq!(c[1], 0.039269908169872414);
    let (x, y, h) = (37.0, 91.0, 1e-4);
    let j = s.jet(x, y);
    let fx = (s.jet(x + h, y).z - s.jet(x - h, y).z) / (2.0 * h);
    let fy = (s.jet(x, y + h).z - s.jet(x, y - h).z) / (2.0 * h);
    let fxx = (s.jet(x + h, y).z - 2.0 * j.z + s.jet(x - h, y).z) / (h * h);
    assert!((fx - j.fx).abs() < 1e-7 && (fy - j.fy).abs() < 1e-7 && (fxx - j.fxx).abs() < 1e-5);
    assert!(HeightSurface::reference(4).is_none());
}
