//! Unit tests of `crate::geometry::paths`.

use super::*;

#[test]
fn study_plan_gives_19800_segments_in_line_major_order() {
    let s = HeightSurface::reference(1).unwrap();
    let plan = PathPlan {
        lines: Some(3),
        ..PathPlan::study()
    };
    let segs = height_surface_segments(&s, &plan).unwrap();
    assert_eq!(segs.len(), 3 * 99);
    // segment (line 1, j 5): starts at x = 5/99*120, y = 70
    let seg = &segs[99 + 5];
    assert!(
        (seg.cc[0][0] - 5.0 / 99.0 * 120.0).abs() < 1e-12 && (seg.cc[0][1] - 70.0).abs() < 1e-12
    );
    assert_eq!(seg.cc.len(), 20);
    assert!((norm(sub(seg.cl[1], seg.cc[19])) - 5.0).abs() < 1e-12);
    let by_spacing = PathPlan {
        lines: None,
        points_per_line: None,
        step_over_mm: Some(35.0),
        cl_spacing_mm: Some(1.2),
        ..PathPlan::study()
    };
    let segs = height_surface_segments(&s, &by_spacing).unwrap();
    assert_eq!(segs.len(), 5 * 100);
    assert!(
        height_surface_segments(
            &s,
            &PathPlan {
                lines: None,
                ..PathPlan::study()
            }
        )
        .is_err()
    );
}

#[test]
fn grid_paths_follow_the_surface() {
    let s = HeightSurface::reference(3).unwrap();
    let (nu, nv) = (61, 31);
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for iv in 0..nv {
        for iu in 0..nu {
            let (p, n) = s.point_normal(iu as f64 * 2.5, iv as f64 * 5.0);
            points.push(p);
            normals.push(n);
        }
    }
    let plan = PathPlan {
        lines: None,
        step_over_mm: Some(10.0),
        points_per_line: Some(100),
        ..PathPlan::study()
    };
    let segs = grid_segments(nu, nv, &points, &normals, &plan).unwrap();
    assert_eq!(segs.len(), 16 * 99);
    // interpolated CC points lie on the true surface to the grid interpolation accuracy
    let worst = segs
        .iter()
        .flat_map(|g| g.cc.iter())
        .map(|p| (s.jet(p[0], p[1]).z - p[2]).abs())
        .fold(0.0, f64::max);
    assert!(worst < 2e-3, "max height deviation {worst} mm");
    assert!(grid_segments(nu, nv, &points[1..], &normals, &plan).is_err());
}
