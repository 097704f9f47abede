//! Decomposition speed at n = 2,025, 20,000 and 250,000 samples.
//!
//! `cargo bench --bench decompose` times our methods on Chen et al. 2024's signal (eq. 23 continued
//! with step 0.01, σ = 0.005 mm noise) and prints one JSON line per size; with
//! `-- --signals DIR` it reads `DIR/signal_N.json` (written by `bench/peers_decompose.py`,
//! which times the Python peers on the same signals in the same run and prints the ratios).
//! Alone it prints the ratio of the default pipeline to Chen et al. 2024's stages 1-4 (baseline).
//! Each line also gives the accuracy of both against the true systematic error (eq. 23
//! without the noise): Pearson r, max and mean abs error (mm), so a speed-up that changes
//! results shows here.

use std::time::Instant;
use truecut::signal::screen::pearson;
use truecut::signal::{DecomposeParams, Method, decompose};

/// The true systematic error of eq. 23 at t = 1 + 0.01 k, mm.
fn truth(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = 1.0 + 0.01 * k as f64;
            let pi = std::f64::consts::PI;
            0.04 * ((1.6 * pi * t).sin() + (0.05 * pi * t).cos() + 4.0 * (-3.0 * t).exp())
        })
        .collect()
}

fn paper_signal(n: usize) -> Vec<f64> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(0);
    let nd = Normal::new(0.0, 0.005).expect("valid sigma");
    truth(n)
        .into_iter()
        .map(|s| s + nd.sample(&mut rng))
        .collect()
}

/// [r, max abs, mean abs] of an estimate against the truth.
fn accuracy(est: &[f64], truth: &[f64]) -> [f64; 3] {
    let e: Vec<f64> = est.iter().zip(truth).map(|(a, b)| (a - b).abs()).collect();
    [
        pearson(est, truth),
        e.iter().copied().fold(0.0, f64::max),
        e.iter().sum::<f64>() / e.len() as f64,
    ]
}

/// Median wall time of `reps` runs, seconds.
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = args
        .iter()
        .position(|a| a == "--signals")
        .and_then(|i| args.get(i + 1))
        .cloned();
    for n in [2025usize, 20_000, 250_000] {
        let x: Vec<f64> = match &dir {
            Some(d) => {
                let text = std::fs::read_to_string(format!("{d}/signal_{n}.json"))
                    .expect("signal file from bench/peers_decompose.py");
                serde_json::from_str(&text).expect("a JSON array of numbers")
            }
            None => paper_signal(n),
        };
        let reps = match n {
            2025 => 7,
            20_000 => 3,
            _ => 1,
        };
        let default = DecomposeParams::default();
        let paper = DecomposeParams {
            refine: false,
            ..Default::default()
        };
        let mut sys_default = Vec::new();
        let mut sys_stages = Vec::new();
        let c2f = time(reps, || {
            sys_default = decompose(&x, Method::CoarseToFine, &default)
                .expect("decomposes")
                .systematic;
        });
        let stages = time(reps, || {
            sys_stages = decompose(&x, Method::CoarseToFine, &paper)
                .expect("decomposes")
                .systematic;
        });
        let tr = truth(n);
        let (a, b) = (accuracy(&sys_default, &tr), accuracy(&sys_stages, &tr));
        let vmd = time(reps, || {
            decompose(&x, Method::Vmd, &default).expect("decomposes");
        });
        println!(
            "{{\"n\": {n}, \"coarse_to_fine_s\": {c2f:.6}, \"stages_1_4_s\": {stages:.6}, \"vmd_s\": {vmd:.6}, \"default_over_stages\": {:.3}, \"default_r_max_mean\": [{:.6}, {:.6}, {:.6}], \"stages_r_max_mean\": [{:.6}, {:.6}, {:.6}]}}",
            c2f / stages,
            a[0],
            a[1],
            a[2],
            b[0],
            b[1],
            b[2]
        );
    }
}
