//! A simulated compensation loop beside Chen et al. 2024's Table 7: a part with a smooth,
//! repeatable systematic error field (~45 µm mean abs) plus random error is probed, the
//! deviations are decomposed, the nominal points are compensated along their normals, and the
//! same machine cuts the compensated points (the same systematic field, fresh random error).

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use truecut::compensation::CompensatedSurface;
use truecut::signal::{DecomposeParams, Method, Order, decompose};

const NU: usize = 45;
const NV: usize = 45;
const SIGMA: f64 = 0.005;

/// Saddle part z = (x² − y²)/200 over ±20 mm with outward (+z side) unit normals.
fn part() -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let (mut p, mut n) = (Vec::new(), Vec::new());
    for iv in 0..NV {
        for iu in 0..NU {
            let x = -20.0 + 40.0 * iu as f64 / (NU - 1) as f64;
            let y = -20.0 + 40.0 * iv as f64 / (NV - 1) as f64;
            p.push([x, y, (x * x - y * y) / 200.0]);
            let (gx, gy) = (x / 100.0, -y / 100.0);
            let l = (gx * gx + gy * gy + 1.0).sqrt();
            n.push([-gx / l, -gy / l, 1.0 / l]);
        }
    }
    (p, n)
}

/// The machine's repeatable systematic deviation (mm, + = material left): a 48 µm offset
/// (e.g. tool deflection), a tilt and a waviness.
fn systematic() -> Vec<f64> {
    let pi = std::f64::consts::PI;
    (0..NU * NV)
        .map(|k| {
            let (u, v) = (
                (k % NU) as f64 / (NU - 1) as f64,
                (k / NU) as f64 / (NV - 1) as f64,
            );
            0.048 + 0.012 * (u - 0.5) - 0.008 * v + 0.010 * (2.0 * pi * u).sin() * (pi * v).cos()
        })
        .collect()
}

fn stats(d: &[f64]) -> (f64, f64) {
    let max = d.iter().map(|v| v.abs()).fold(0.0, f64::max);
    (max, d.iter().map(|v| v.abs()).sum::<f64>() / d.len() as f64)
}

#[test]
fn compensation_loop_reaches_the_random_floor() {
    let (nominal, normals) = part();
    let sys = systematic();
    let floor = SIGMA * (2.0 / std::f64::consts::PI).sqrt();
    let grid = |order, refine| DecomposeParams {
        nu: Some(NU),
        nv: Some(NV),
        order,
        refine,
        ..Default::default()
    };
    // name, offsets rule; Chen et al. 2024 Table 7 row (before max, before mean, after max, after
    // mean)
    type Rule = Box<dyn Fn(&[f64]) -> Vec<f64>>;
    let rules: Vec<(&str, Rule, [f64; 4])> = vec![
        (
            "direct (offset = measured deviation)",
            Box::new(|m: &[f64]| m.to_vec()),
            [0.0575, 0.0435, 0.0201, 0.0124],
        ),
        (
            "VMD alone, row-major",
            Box::new(move |m: &[f64]| {
                decompose(m, Method::Vmd, &grid(Order::RowMajor, false))
                    .unwrap()
                    .systematic
            }),
            [0.0594, 0.0449, 0.0186, 0.0082],
        ),
        (
            "C2F stages 1-4, row-major (paper)",
            Box::new(move |m: &[f64]| {
                decompose(m, Method::CoarseToFine, &grid(Order::RowMajor, false))
                    .unwrap()
                    .systematic
            }),
            [0.0580, 0.0472, 0.0159, 0.0059],
        ),
        (
            "C2F default (refined, 2-D)",
            Box::new(move |m: &[f64]| {
                decompose(m, Method::CoarseToFine, &grid(Order::TwoD, true))
                    .unwrap()
                    .systematic
            }),
            [0.0580, 0.0472, 0.0159, 0.0059],
        ),
    ];
    println!("floor σ·sqrt(2/π) = {floor:.5} mm");
    println!("rule | ours before max/mean -> after max/mean (Δmax, Δmean) | paper Table 7");
    let seeds = 5u64;
    let mut after_means = Vec::new();
    for (name, rule, paper) in &rules {
        let (mut b, mut a) = ([0.0; 2], [0.0; 2]);
        for seed in 0..seeds {
            let mut rng = rand::rngs::StdRng::seed_from_u64(100 + seed);
            let nd = Normal::new(0.0, SIGMA).unwrap();
            let measured: Vec<f64> = sys.iter().map(|s| s + nd.sample(&mut rng)).collect();
            let offsets = rule(&measured);
            // Compensated target points, through the reconstructed surface at the probe grid.
            let surf = CompensatedSurface::new(NU, NV, &nominal, &normals, &offsets).unwrap();
            let target = surf.resample(NU, NV, None).unwrap();
            // The machine cuts the target with the same systematic error and new random error:
            // cut = target + (sys + e2)·n, measured against the nominal along n.
            let after: Vec<f64> = (0..NU * NV)
                .map(|k| {
                    let dev = sys[k] + nd.sample(&mut rng);
                    let cut: Vec<f64> = (0..3)
                        .map(|c| target.points[k][c] + dev * normals[k][c])
                        .collect();
                    (0..3)
                        .map(|c| (cut[c] - nominal[k][c]) * normals[k][c])
                        .sum()
                })
                .collect();
            let (bm, bmean) = stats(&measured);
            let (am, amean) = stats(&after);
            b[0] += bm / seeds as f64;
            b[1] += bmean / seeds as f64;
            a[0] += am / seeds as f64;
            a[1] += amean / seeds as f64;
        }
        println!(
            "{name} | {:.4}/{:.4} -> {:.4}/{:.4} ({:+.1} %, {:+.1} %) | {:.4}/{:.4} -> {:.4}/{:.4} ({:+.1} %, {:+.1} %)",
            b[0],
            b[1],
            a[0],
            a[1],
            100.0 * (a[0] / b[0] - 1.0),
            100.0 * (a[1] / b[1] - 1.0),
            paper[0],
            paper[1],
            paper[2],
            paper[3],
            100.0 * (paper[2] / paper[0] - 1.0),
            100.0 * (paper[3] / paper[1] - 1.0)
        );
        after_means.push(a[1]);
    }
    let best = after_means[3];
    assert!(
        best <= 1.10 * floor,
        "after-compensation mean abs {best:.5} not within 10 % of the floor {floor:.5}"
    );
    // Direct compensation doubles the random variance (after ≈ σ√2·sqrt(2/π)).
    assert!(after_means[0] > 1.3 * floor, "{after_means:?}");
    assert!(
        best < after_means[1] && best < after_means[2],
        "{after_means:?}"
    );
}
