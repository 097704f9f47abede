//! Unit tests of `crate::compensation::surface`.

use super::*;

fn saddle(nu: usize, nv: usize) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut p = Vec::new();
    let mut n = Vec::new();
    for iv in 0..nv {
        for iu in 0..nu {
            let x = -20.0 + 40.0 * iu as f64 / (nu - 1) as f64;
            let y = -20.0 + 40.0 * iv as f64 / (nv - 1) as f64;
            p.push([x, y, (x * x - y * y) / 200.0]);
            let (gx, gy) = (x / 100.0, -y / 100.0);
            let l = (gx * gx + gy * gy + 1.0).sqrt();
            n.push([-gx / l, -gy / l, 1.0 / l]);
        }
    }
    (p, n)
}

#[test]
fn reproduces_grid_points_and_offsets_cl() {
    let (nu, nv) = (9, 7);
    let (p, n) = saddle(nu, nv);
    let off: Vec<f64> = (0..nu * nv)
        .map(|k| 0.01 + 0.001 * (k % 5) as f64)
        .collect();
    let s = CompensatedSurface::new(nu, nv, &p, &n, &off).unwrap();
    let g = s.resample(nu, nv, Some(3.0)).unwrap();
    let want = compensate_points(&p, &n, &off).unwrap();
    for k in 0..nu * nv {
        for c in 0..3 {
            assert!((g.points[k][c] - want[k][c]).abs() < 1e-9);
            let cl = want[k][c] + 3.0 * n[k][c];
            assert!((g.cl.as_ref().unwrap()[k][c] - cl).abs() < 1e-9);
        }
        assert!((g.offsets[k] - off[k]).abs() < 1e-12);
    }
}

#[test]
fn denser_sampling_stays_on_the_surface() {
    let (p, n) = saddle(21, 21);
    let off = vec![0.02; 21 * 21];
    let s = CompensatedSurface::new(21, 21, &p, &n, &off).unwrap();
    let g = s.resample(61, 41, None).unwrap();
    for (q, nrm) in g.points.iter().zip(&g.normals) {
        // Undo the offset along the normal: the point must be back on z = (x²-y²)/200.
        let (x, y, z) = (
            q[0] + 0.02 * nrm[0],
            q[1] + 0.02 * nrm[1],
            q[2] + 0.02 * nrm[2],
        );
        assert!((z - (x * x - y * y) / 200.0).abs() < 2e-5, "{x} {y} {z}");
    }
    assert!(s.resample(1, 5, None).is_err());
    assert!(s.resample(5, 5, Some(-1.0)).is_err());
}
