//! Unit tests of `crate::gap::part`.

use super::*;
use rand::{RngExt, SeedableRng};

/// An elliptic dome z = 30 − x²/300 − y²/800 on a 24×20 grid centred at (150, 80) mm.
fn dome() -> PartGrid {
    let (nu, nv) = (24, 20);
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for iv in 0..nv {
        for iu in 0..nu {
            let (x, y) = (
                -40.0 + 80.0 * iu as f64 / (nu - 1) as f64,
                -30.0 + 60.0 * iv as f64 / (nv - 1) as f64,
            );
            points.push([150.0 + x, 80.0 + y, 30.0 - x * x / 300.0 - y * y / 800.0]);
            let g = [x / 150.0, y / 400.0, 1.0];
            let l = (g[0] * g[0] + g[1] * g[1] + 1.0f64).sqrt();
            normals.push([g[0] / l, g[1] / l, g[2] / l]);
        }
    }
    PartGrid {
        nu,
        nv,
        points,
        normals,
    }
}

fn block(grid: &PartGrid, truth: usize, sigma: f64, rng: &mut impl rand::Rng) -> PartBlock {
    let n = grid.nu * grid.nv;
    let c = centroid(&grid.points);
    let time: Vec<f64> = (0..n).map(|k| k as f64).collect();
    let approach: Vec<[f64; 3]> = grid.normals.iter().map(|v| [-v[0], -v[1], -v[2]]).collect();
    let normal = rand_distr::Normal::new(0.0, sigma).unwrap();
    // the simulation predicts a smooth form error the truth also has
    let predicted: Vec<f64> = grid
        .points
        .iter()
        .map(|p| 0.004 * ((p[0] - 150.0) / 20.0).sin())
        .collect();
    let measured = (0..n)
        .map(|k| {
            let (p, nn) = (grid.points[k], grid.normals[k]);
            let extra = match truth {
                1 => {
                    let t = [0.006, -0.004, 0.003];
                    let w = [40e-6, -30e-6, 60e-6];
                    let r = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
                    let d = [
                        t[0] + w[1] * r[2] - w[2] * r[1],
                        t[1] + w[2] * r[0] - w[0] * r[2],
                        t[2] + w[0] * r[1] - w[1] * r[0],
                    ];
                    d[0] * nn[0] + d[1] * nn[1] + d[2] * nn[2]
                }
                2 => 0.012 * (1.0 - (-time[k] / 300.0).exp()) * nn[2],
                3 => {
                    let a = approach[k];
                    let th = a[1].atan2(a[0]);
                    let pre = 0.003 + 0.002 * (3.0 * th + 0.4).cos() * (1.0 - a[2] * a[2]) * 40.0;
                    pre * (a[0] * nn[0] + a[1] * nn[1] + a[2] * nn[2])
                }
                _ => 0.0,
            };
            predicted[k] + extra + rng.sample(normal)
        })
        .collect();
    PartBlock {
        measured,
        predicted,
        time,
        approach,
    }
}

#[test]
fn finds_each_part_effect_and_none_and_shrinks_validation() {
    let grid = dome();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    for (truth, expected) in [
        (0, PartEffect::None),
        (1, PartEffect::SetupMisalignment),
        (2, PartEffect::ThermalDrift),
        (3, PartEffect::ProbePretravel),
    ] {
        let main = block(&grid, truth, 0.0004, &mut rng);
        let val = block(&grid, truth, 0.0004, &mut rng);
        let d = diagnose_part(&grid, &main, Some(&val), 0.05).unwrap();
        assert_eq!(
            d.verdict,
            expected,
            "truth {truth}: {:?}",
            d.effects
                .iter()
                .map(|e| (e.effect, e.score))
                .collect::<Vec<_>>()
        );
        let (_, _, before, after) = d.validation.unwrap();
        if truth == 0 {
            assert_eq!(before, after);
        } else {
            assert!(
                after < 0.3 * before,
                "truth {truth}: validation rms {before} -> {after}"
            );
            assert!(d.gap_after.rms < 0.3 * d.gap_before.rms);
        }
    }
}

#[test]
fn misalignment_rotation_is_reported_about_the_centroid() {
    let grid = dome();
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let main = block(&grid, 1, 0.0001, &mut rng);
    let d = diagnose_part(&grid, &main, None, 0.05).unwrap();
    let p = &d
        .effects
        .iter()
        .find(|e| e.effect == PartEffect::SetupMisalignment)
        .unwrap()
        .params;
    let get = |name: &str| p.iter().find(|(n, _)| n == name).unwrap().1;
    assert!((get("rz_rad") - 60e-6).abs() < 3e-6, "{p:?}");
    // on a shallow dome an x shift and a rotation about y are nearly the same motion, so
    // only the well-conditioned ones are checked: the normal shift and the spin about z
    assert!((get("tz_mm") - 0.003).abs() < 0.0005, "{p:?}");
    assert!(d.gap_after.rms < 0.0002, "{:?}", d.gap_after);
    assert!((get("centroid_x_mm") - 150.0).abs() < 1e-9);
}

#[test]
fn regions_rank_a_local_bump_first() {
    let grid = dome();
    let mut r = vec![0.0; grid.nu * grid.nv];
    r[19 * grid.nu + 23] = 0.01;
    r[0] = 0.001;
    let reg = regions(&grid, &r);
    assert_eq!(reg[0].u, [18, 23]);
    assert_eq!(reg[0].v, [15, 19]);
    assert!(reg[0].label.starts_with("corner (high u, high v)"));
    assert!((reg[0].share - 100.0 / 101.0).abs() < 1e-12);
}
