//! The paper's simulation (Chen et al. 2024, section 3, eq. 23) over 20 seeds, beside its Table 3
//! and beside the Python peers (peer study §1, `tests/data/decomposition/REPORT.md`).
//!
//! x(t) = 0.04·[sin(1.6πt) + cos(0.05πt) + 4·e^(−3t)] mm, t = 1 … 21.24 step 0.01 (2,025
//! samples), plus N(0, σ = 0.005 mm) noise (σ, not variance: peer study §2 shows only this reading
//! is consistent with Table 3). Our noise comes from rand's StdRng with seeds 0..19 (not
//! numpy's), so per-seed values differ from the peers'; the 20-seed means are comparable.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use truecut::signal::screen::pearson;
use truecut::signal::{DecomposeParams, Method, decompose};

fn truth() -> Vec<f64> {
    (0..2025)
        .map(|k| {
            let t = 1.0 + 0.01 * k as f64;
            let pi = std::f64::consts::PI;
            0.04 * ((1.6 * pi * t).sin() + (0.05 * pi * t).cos() + 4.0 * (-3.0 * t).exp())
        })
        .collect()
}

/// (corr, max abs, mean abs) of an estimate against the truth, mm.
fn metrics(est: &[f64], truth: &[f64]) -> [f64; 3] {
    let e: Vec<f64> = est.iter().zip(truth).map(|(a, b)| (a - b).abs()).collect();
    [
        pearson(est, truth),
        e.iter().copied().fold(0.0, f64::max),
        e.iter().sum::<f64>() / e.len() as f64,
    ]
}

#[test]
fn table3_twenty_seeds() {
    let truth = truth();
    let noisy: Vec<Vec<f64>> = (0..20u64)
        .map(|seed| {
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let nd = Normal::new(0.0, 0.005).unwrap();
            truth.iter().map(|t| t + nd.sample(&mut rng)).collect()
        })
        .collect();
    // name, method, params, paper (corr, max, mean), peers' 20-seed mean (corr, max, mean)
    type Row = (&'static str, Method, DecomposeParams, [f64; 3], [f64; 3]);
    let rows: Vec<Row> = vec![
        (
            "VMD",
            Method::Vmd,
            DecomposeParams::default(),
            [0.9991, 0.0106, 0.0015],
            [0.99957, 0.00689, 0.00113],
        ),
        (
            "EMD",
            Method::Emd,
            DecomposeParams::default(),
            [0.9993, 0.0088, 0.0013],
            [0.98062, 0.02562, 0.00423],
        ),
        (
            "wavelet db4 (noise level rule)",
            Method::Wavelet,
            DecomposeParams::default(),
            [0.9994, 0.0083, 0.0012],
            [0.99574, 0.01065, 0.00344],
        ),
        (
            "C2F stages 1-4 (paper, refine off)",
            Method::CoarseToFine,
            DecomposeParams {
                refine: false,
                ..Default::default()
            },
            [0.9998, 0.0039, 0.0008],
            [0.99929, 0.00647, 0.00134],
        ),
        (
            "C2F default (refined)",
            Method::CoarseToFine,
            DecomposeParams::default(),
            [0.9998, 0.0039, 0.0008],
            [0.99929, 0.00647, 0.00134],
        ),
    ];
    println!(
        "method | ours corr / max / mean (worst mean abs) | paper Table 3 | peers (peer study)"
    );
    let mut results = Vec::new();
    for (name, method, params, paper, peer) in &rows {
        let mut acc = [0.0; 3];
        let mut worst_mean: f64 = 0.0;
        let mut carriers = 0;
        for x in &noisy {
            let d = decompose(x, *method, params).unwrap();
            // Clean simulated data: the flyer screen names nothing, so the result is the
            // plain decomposition's (flyers::tests checks the bit-for-bit identity).
            assert!(
                d.outliers.is_empty(),
                "{name}: flyers named {:?}",
                d.outliers
            );
            for (i, (s, r)) in d.systematic.iter().zip(&d.random).enumerate() {
                assert!((s + r - x[i]).abs() < 1e-12);
            }
            if let Some(st) = &d.components.stages {
                carriers += usize::from(!st.narrow_band.is_empty());
            }
            let m = metrics(&d.systematic, &truth);
            for i in 0..3 {
                acc[i] += m[i] / 20.0;
            }
            worst_mean = worst_mean.max(m[2]);
        }
        println!(
            "{name} | {:.5} / {:.5} / {:.5} ({worst_mean:.5}) | {:.4} / {:.4} / {:.4} | {:.5} / {:.5} / {:.5}",
            acc[0], acc[1], acc[2], paper[0], paper[1], paper[2], peer[0], peer[1], peer[2]
        );
        if carriers > 0 {
            println!("  (a narrow-band carrier was refitted in {carriers} of 20 draws)");
        }
        results.push(acc);
    }
    let (vmd, c2f_paper, c2f) = (results[0], results[3], results[4]);
    // Faithful baselines: our VMD row sits in the peers' band (peer study §4: corr ≈ 0.9996,
    // max ≈ 0.006–0.007 (ours 0.0075 with other noise draws), mean ≈ 0.0011).
    assert!(vmd[0] > 0.9994 && vmd[2] < 0.0013, "VMD row {vmd:?}");
    // The paper's stages as published stay short of Table 3 (peer study §1: 0.00134 mean abs).
    assert!(
        c2f_paper[2] > 0.0009,
        "stages 1-4 unexpectedly reach the paper: {c2f_paper:?}"
    );
    // The default meets Chen et al. 2024's coarse-to-fine max and mean abs.
    assert!(
        c2f[1] <= 0.0039,
        "default max abs {:.5} > paper 0.0039",
        c2f[1]
    );
    assert!(
        c2f[2] <= 0.0008,
        "default mean abs {:.5} > paper 0.0008",
        c2f[2]
    );
    // Correlation: Chen et al. 2024's 0.9998 is reached since stage 5 refits the sinusoid's VMD
    // mode as a carrier with a slow envelope (≈ 0.99982; with the broadband smoother alone
    // it was 0.99973, the level peer study §1's truth-tuned smoother reaches, 0.99977).
    assert!(
        c2f[0] >= 0.9998,
        "default corr {:.5} < paper 0.9998",
        c2f[0]
    );
    assert!(c2f[2] < 0.7 * c2f_paper[2] && c2f[2] < vmd[2]);
}

/// The automatic K (instantaneous-frequency-mean rule) on Chen et al. 2024's signal: Chen et al.
/// 2024 found K = 7 (section 3.1). The rule is noisy from draw to draw (our 8 seeds give
/// 7 8 7 10 7 6 5 7), so we check the median over the seeds, not every seed.
#[test]
fn auto_k_median_is_the_papers_seven() {
    use truecut::signal::vmd::{VmdParams, choose_k};
    let truth = truth();
    let mut ks: Vec<usize> = (0..8u64)
        .map(|seed| {
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let nd = Normal::new(0.0, 0.005).unwrap();
            let x: Vec<f64> = truth.iter().map(|t| t + nd.sample(&mut rng)).collect();
            choose_k(&x, &VmdParams::default(), 10).unwrap()
        })
        .collect();
    println!("automatic K per seed: {ks:?} (paper: 7)");
    ks.sort_unstable();
    assert_eq!(ks[ks.len() / 2], 7, "{ks:?}");
    assert!(ks.iter().all(|k| (2..=10).contains(k)));
}
