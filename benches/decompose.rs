//! Decomposition speed at n = 2,025, 20,000 and 250,000 samples.
//!
//! `cargo bench --bench decompose` times our methods on the paper's signal (eq. 23 continued
//! with step 0.01, σ = 0.005 mm noise) and prints one JSON line per size; with
//! `-- --signals DIR` it reads `DIR/signal_N.json` (written by `bench/peers_decompose.py`,
//! which times the Python peers on the same signals in the same run and prints the ratios).
//! Alone it prints the ratio of the default pipeline to the paper's stages 1-4 (baseline).

use std::time::Instant;
use truecut::signal::{DecomposeParams, Method, decompose};

fn paper_signal(n: usize) -> Vec<f64> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(0);
    let nd = Normal::new(0.0, 0.005).expect("valid sigma");
    (0..n)
        .map(|k| {
            let t = 1.0 + 0.01 * k as f64;
            let pi = std::f64::consts::PI;
            0.04 * ((1.6 * pi * t).sin() + (0.05 * pi * t).cos() + 4.0 * (-3.0 * t).exp())
                + nd.sample(&mut rng)
        })
        .collect()
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
        let c2f = time(reps, || {
            decompose(&x, Method::CoarseToFine, &default).expect("decomposes");
        });
        let stages = time(reps, || {
            decompose(&x, Method::CoarseToFine, &paper).expect("decomposes");
        });
        let vmd = time(reps, || {
            decompose(&x, Method::Vmd, &default).expect("decomposes");
        });
        println!(
            "{{\"n\": {n}, \"coarse_to_fine_s\": {c2f:.6}, \"stages_1_4_s\": {stages:.6}, \"vmd_s\": {vmd:.6}, \"default_over_stages\": {:.3}}}",
            c2f / stages
        );
    }
}
