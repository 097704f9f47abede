//! Oracle tests of the exact step error against the Python study's test vectors
//! (`tests/data/step/testvectors*.csv`: every 97th segment of the three surfaces,
//! 615 rows; labels from 2001 dense points on the true surface).

use super::solver::*;
use crate::geometry::error::Error;
use crate::geometry::spline::{CubicSpline3, Parameterization};

pub(crate) struct Vector {
    pub surface: u32,
    pub cl: [[f64; 3]; 2],
    pub cc: Vec<[f64; 3]>,
    pub fxx_mid: f64,
    pub convex: bool,
    pub lmin_mm: f64,
    pub lmax_mm: f64,
    pub e_um: f64,
}

pub(crate) fn load_vectors() -> Vec<Vector> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/step/");
    let main = std::fs::read_to_string(format!("{dir}testvectors.csv"))
        .expect("reference test vectors (tests/data/step)");
    let pm = std::fs::read_to_string(format!("{dir}testvectors_pm.csv"))
        .expect("reference test vectors (tests/data/step)");
    let mut pts: std::collections::HashMap<(u32, u32, u32), Vec<[f64; 3]>> = Default::default();
    for line in pm.lines().skip(1) {
        let f: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
        pts.entry((f[0] as u32, f[1] as u32, f[2] as u32))
            .or_default()
            .push([f[4], f[5], f[6]]);
    }
    main.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
            let key = (f[0] as u32, f[1] as u32, f[2] as u32);
            Vector {
                surface: key.0,
                cl: [[f[15], f[16], f[17]], [f[18], f[19], f[20]]],
                cc: pts.remove(&key).expect("cc points of every vector"),
                fxx_mid: f[21],
                convex: f[22] == 1.0,
                lmin_mm: f[23],
                lmax_mm: f[24],
                e_um: f[27],
            }
        })
        .collect()
}

/// Every vector: our exact error equals the study's label where both take the same branch
/// (to 2e-5 µm: the spline through 20 points vs the true surface; measured 3.5e-6), and where the convexity
/// decision differs (|f_xx| ~ 0 at the middle) it equals the study's other branch.
#[test]
fn matches_study_test_vectors() {
    let vectors = load_vectors();
    assert_eq!(vectors.len(), 615);
    let mut solver = StepErrorSolver::default().both_branches(true);
    let (mut worst, mut flips, mut n_infl) = (0.0f64, 0, 0);
    for (i, v) in vectors.iter().enumerate() {
        assert_eq!(v.cc.len(), 20);
        let e = solver.solve(5.0, v.cl, &v.cc).unwrap();
        n_infl += e.inflection as usize;
        let e_um = e.error_mm * 1000.0;
        // Both one-sided errors against the study's L_min / L_max (dense points on the true curve).
        let (g, u) = if e.convex {
            (e.signed_mm, e.other_side_mm)
        } else {
            (e.other_side_mm, e.signed_mm)
        };
        assert!(
            ((5.0 - v.lmin_mm) - g).abs() * 1000.0 < 2e-5,
            "row {i}: R - Lmin {g} vs {}",
            5.0 - v.lmin_mm
        );
        assert!(
            ((v.lmax_mm - 5.0) - u).abs() * 1000.0 < 2e-5,
            "row {i}: Lmax - R {u} vs {}",
            v.lmax_mm - 5.0
        );
        if e.convex == v.convex {
            let d = (e_um - v.e_um).abs();
            worst = worst.max(d);
            assert!(
                d < 2e-5,
                "row {i} (surface {}): {e_um} vs {} um",
                v.surface,
                v.e_um
            );
        } else {
            flips += 1;
            assert!(
                v.fxx_mid.abs() < 1e-4,
                "row {i}: convexity differs with f_xx = {}",
                v.fxx_mid
            );
            let other = if e.convex {
                (5.0 - v.lmin_mm) * 1000.0
            } else {
                (v.lmax_mm - 5.0) * 1000.0
            };
            assert!(
                (e_um - other.abs()).abs() < 2e-5,
                "row {i}: {e_um} vs other branch {other}"
            );
        }
    }
    eprintln!(
        "test vectors: max |ours - study| {worst:.2e} um, convexity flips {flips}, inflections {n_infl}"
    );
    assert!(
        flips <= 3,
        "{flips} convexity decisions differ from the study"
    );
}

/// The lane path (uniform knots, used by `solve` and `solve_batch`) against the general spline
/// path on the same segments, both branches: the same decisions, values to 1e-12 mm.
#[test]
fn lane_path_matches_spline_path() {
    let mut lanes = StepErrorSolver::default().both_branches(true);
    let mut general = StepErrorSolver::default().both_branches(true);
    for (i, v) in load_vectors().iter().enumerate() {
        let a = lanes.solve(5.0, v.cl, &v.cc).unwrap();
        let b = general.solve_via_spline(5.0, v.cl, &v.cc).unwrap();
        assert_eq!(
            (a.convex, a.inflection),
            (b.convex, b.inflection),
            "row {i}"
        );
        for (x, y) in [
            (a.error_mm, b.error_mm),
            (a.other_side_mm, b.other_side_mm),
            (a.point[0], b.point[0]),
            (a.point[2], b.point[2]),
        ] {
            assert!((x - y).abs() < 1e-12, "row {i}: {x} vs {y}");
        }
        assert!((a.t - b.t).abs() < 1e-7, "row {i}: t {} vs {}", a.t, b.t);
    }
}

/// Segments of a circular CC arc (radius `rc`, in the xz plane, convex), m points, ball radius 5.
fn arc_segment(m: usize, phase: f64, rc: f64) -> ([[f64; 3]; 2], Vec<[f64; 3]>) {
    let cc: Vec<[f64; 3]> = (0..m)
        .map(|k| {
            let th = phase + 0.02 * k as f64 / (m - 1) as f64;
            [rc * th.sin(), 0.1 * k as f64, rc * th.cos()]
        })
        .collect();
    let cl = [0, m - 1].map(|k| {
        let p = cc[k];
        let n = [p[0] / rc, 0.0, p[2] / rc];
        [p[0] + 5.0 * n[0], p[1], p[2] + 5.0 * n[2]]
    });
    (cl, cc)
}

/// A batch gives bit for bit what one segment at a time gives, with groups of four, mixed m
/// (3, which takes the spline path, to 30), and the first bad segment's index on error.
#[test]
fn batch_equals_one_at_a_time() {
    let vectors = load_vectors();
    type Owned = ([[f64; 3]; 2], Vec<[f64; 3]>);
    let mut segs: Vec<Owned> = vectors.iter().map(|v| (v.cl, v.cc.clone())).collect();
    for (i, m) in [3usize, 4, 4, 5, 4, 4, 4, 4, 30, 7, 7, 7, 7, 7, 3, 6]
        .into_iter()
        .enumerate()
    {
        segs.insert(7 * i + 3, arc_segment(m, 0.1 * i as f64, 40.0 + i as f64));
    }
    for both in [false, true] {
        let mut one = StepErrorSolver::default().both_branches(both);
        let want: Vec<StepError> = segs
            .iter()
            .map(|(cl, cc)| one.solve(5.0, *cl, cc).unwrap())
            .collect();
        let mut batch = StepErrorSolver::default().both_branches(both);
        let got = batch
            .solve_batch(5.0, segs.iter().map(|(cl, cc)| (*cl, &cc[..])))
            .unwrap();
        assert_eq!(got.len(), want.len());
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            // NaN != NaN: compare the bits.
            assert_eq!(
                (
                    g.error_mm.to_bits(),
                    g.other_side_mm.to_bits(),
                    g.t.to_bits()
                ),
                (
                    w.error_mm.to_bits(),
                    w.other_side_mm.to_bits(),
                    w.t.to_bits()
                ),
                "segment {i} (both branches: {both})"
            );
            assert_eq!(
                (g.point, g.convex, g.inflection),
                (w.point, w.convex, w.inflection)
            );
        }
    }
    let mut bad = segs.clone();
    bad[10].1[2][1] = f64::NAN;
    let e = StepErrorSolver::default()
        .solve_batch(5.0, bad.iter().map(|(cl, cc)| (*cl, &cc[..])))
        .unwrap_err();
    assert!(matches!(e, Error::InSegment { index: 10, .. }), "{e:?}");
}

/// The extremum search against a slow obvious one on the same spline: Brent's search to
/// 1e-10 on every piece (the best of all of them), both branches: equal to 1e-12 mm
/// (1e-9 µm, inside the 1e-6 µm promise) on every test vector.
#[test]
fn extremum_matches_exhaustive_search_on_the_spline() {
    let mut solver = StepErrorSolver::default().both_branches(true);
    for (i, v) in load_vectors().iter().enumerate() {
        let e = solver.solve(5.0, v.cl, &v.cc).unwrap();
        let sp = CubicSpline3::through(&v.cc, Parameterization::Uniform).unwrap();
        let a = v.cl[0];
        let d = crate::numeric::vec3::sub(v.cl[1], a);
        let u = crate::numeric::vec3::scale(d, 1.0 / crate::numeric::vec3::norm(d));
        let dist = |t: f64| {
            crate::numeric::vec3::norm(crate::numeric::vec3::cross(
                crate::numeric::vec3::sub(sp.eval(t), a),
                u,
            ))
        };
        let knots = sp.knots();
        let search = |sign: f64| {
            knots
                .windows(2)
                .map(|w| {
                    crate::numeric::brent::minimize(|t| sign * dist(t), w[0], w[1], 1e-10, 200).1
                })
                .chain(knots.iter().map(|&t| sign * dist(t)))
                .fold(f64::INFINITY, f64::min)
                * sign
        };
        let (lmin, lmax) = (search(1.0), search(-1.0));
        let (l_best, l_other) = if e.convex { (lmin, lmax) } else { (lmax, lmin) };
        assert!(
            (e.distance_mm - l_best).abs() < 1e-12,
            "row {i}: {} vs {l_best}",
            e.distance_mm
        );
        let other = if e.convex {
            l_other - 5.0
        } else {
            5.0 - l_other
        };
        assert!(
            (e.other_side_mm - other).abs() < 1e-12,
            "row {i}: other side {} vs {other}",
            e.other_side_mm
        );
    }
}
