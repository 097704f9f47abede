//! Decomposition speed at n = 2,025, 20,000 and 250,000 samples.
//!
//! `cargo bench --bench decompose` times our methods on Chen et al. 2024's signal (eq. 23 continued
//! with step 0.01, σ = 0.005 mm noise) and prints one JSON line per size; with
//! `-- --signals DIR` it reads `DIR/signal_N.json` (written by `bench/peers_decompose.py`,
//! which times the Python peers on the same signals in the same run and prints the ratios),
//! `-- --sizes 2025 20000` limits the sizes and `-- --reps N` sets the runs per figure.
//! `-- --write-signals DIR` (with `--sizes`) only writes this bench's own signals (seeded
//! `StdRng` noise, below) as `DIR/signal_N.json` and exits, so that
//! `bench/peers_decompose.py --signals bench` can time the peers on them (issue 41: the
//! peer's VMD converges on them in fewer iterations than on numpy's seed-0 noise).
//! Alone it prints the ratio of the default pipeline to Chen et al. 2024's stages 1-4 (baseline).
//! Each line also gives the accuracy of both against the true systematic error (eq. 23
//! without the noise): Pearson r, max and mean abs error (mm), so a speed-up that changes
//! results shows here.
//!
//! Each line also carries:
//! - `http_s`: `POST /v1/decompose` end to end on a server started in this process (loopback,
//!   the JSON body encoded before the clock starts, the answer's bytes read);
//! - `profile_ms`: where the default pipeline's time goes, each stage timed alone on the same
//!   input (flyer screen, VMD, screening + EMD, wavelet, stage-5 refinement, JSON decode of the
//!   request and encode of the answer as the API does them).
//!
//! `-- --split` (with `--sizes`, `--reps`) times instead VMD alone and the default pipeline
//! with the VMD pinned to one thread and to two (`truecut::signal::vmd::with_threads`),
//! interleaved in the same run, and prints the one-thread / two-thread ratios and how many
//! systematic samples differ between the two and by how much (issue 25: none, so the split
//! is a matter of speed only).
//!
//! Times are the best of `reps` runs (the machine is shared: the minimum is the least
//! disturbed run).

use std::time::Instant;
use truecut::signal::coarse_to_fine::narrow_band_part;
use truecut::signal::emd::emd;
use truecut::signal::flyers::suspects;
use truecut::signal::screen::{pearson, screen, sum_selected};
use truecut::signal::vmd::{VmdParams, vmd, with_threads};
use truecut::signal::wavelet::{Wavelet, denoise};
use truecut::signal::whittaker::whittaker;
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

/// Best (least disturbed) wall time of `reps` runs, seconds.
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The request body of `POST /v1/decompose` as the bench decodes it.
#[derive(serde::Deserialize)]
struct Body {
    signal: Vec<f64>,
}

/// Milliseconds per stage of the default 1-D pipeline on `x` (see the module doc).
fn profile(x: &[f64], body: &str, reps: usize) -> Vec<(&'static str, f64)> {
    let p = DecomposeParams::default();
    let ms = |f: &mut dyn FnMut()| time(reps, f) * 1e3;
    let mut out = Vec::new();
    out.push((
        "json_decode",
        ms(&mut || {
            let b: Body = serde_json::from_str(body).expect("decodes");
            assert_eq!(b.signal.len(), x.len());
        }),
    ));
    out.push((
        "flyers",
        ms(&mut || {
            suspects(x, None, &p.flyers);
        }),
    ));
    let v = vmd(x, &p.vmd).expect("vmd");
    out.push((
        "vmd",
        ms(&mut || {
            vmd(x, &p.vmd).expect("vmd");
        }),
    ));
    let (_, strong) = screen(&v.modes, x, p.threshold);
    let n = x.len();
    let x1 = sum_selected(&v.modes, &strong, n);
    out.push((
        "screen_emd",
        ms(&mut || {
            screen(&v.modes, x, p.threshold);
            let e = emd(&x1, &p.emd).expect("emd");
            let mut comps = e.imfs;
            comps.push(e.residue);
            screen(&comps, x, p.threshold);
        }),
    ));
    let w = Wavelet::new(&p.wavelet).expect("db4");
    let weak: Vec<bool> = strong.iter().map(|s| !s).collect();
    let wk = sum_selected(&v.modes, &weak, n);
    out.push((
        "wavelet",
        ms(&mut || {
            let level = p.wavelet_level.resolve(&wk, &w);
            denoise(&wk, &w, Some(level));
        }),
    ));
    let smooth = |r: &[f64]| whittaker(r, 4, None);
    out.push((
        "refine",
        ms(&mut || {
            narrow_band_part(x, &v.modes, &strong, Some(4), &smooth).expect("refine");
        }),
    ));
    let d = decompose(x, Method::CoarseToFine, &p).expect("decomposes");
    out.push((
        "json_encode",
        ms(&mut || {
            // As the API's stateless route: straight to bytes.
            let b = serde_json::to_vec(&d).expect("encodes");
            assert!(b.len() > n);
        }),
    ));
    out.push((
        "total_in_process",
        ms(&mut || {
            decompose(x, Method::CoarseToFine, &p).expect("decomposes");
        }),
    ));
    out
}

/// Best wall time of `reps` `POST /v1/decompose` round trips with `body`, seconds.
fn http(rt: &tokio::runtime::Runtime, base: &str, body: &str, reps: usize) -> f64 {
    // reqwest is built with rustls but no default crypto provider (Cargo.toml).
    truecut::cli::client::install_crypto_provider();
    let client = reqwest::Client::new();
    let url = format!("{base}/v1/decompose");
    let body = bytes::Bytes::from(body.to_owned());
    rt.block_on(async {
        let mut best = f64::INFINITY;
        for _ in 0..reps {
            let t0 = Instant::now();
            let r = client
                .post(&url)
                .header("content-type", "application/json")
                .body(body.clone())
                .send()
                .await
                .expect("POST /v1/decompose");
            assert!(r.status().is_success(), "status {}", r.status());
            let bytes = r.bytes().await.expect("answer");
            best = best.min(t0.elapsed().as_secs_f64());
            assert!(bytes.len() > 100);
        }
        best
    })
}

/// `--split`: best of `reps` interleaved runs of VMD alone and of the default pipeline, VMD
/// pinned to one thread and to two; one JSON line per size with both ratios one / two.
fn split(sizes: &[usize], reps: usize) {
    for &n in sizes {
        let x = paper_signal(n);
        let (p, vp) = (DecomposeParams::default(), VmdParams::default());
        // best[stage][threads - 1], stage 0 = VMD alone, 1 = the default pipeline
        let mut best = [[f64::INFINITY; 2]; 2];
        let mut systematic: [Vec<f64>; 2] = Default::default();
        for _ in 0..reps {
            for threads in [1, 2] {
                let v = time(1, || {
                    with_threads(threads, || vmd(&x, &vp)).expect("VMD");
                });
                let c = time(1, || {
                    systematic[threads - 1] =
                        with_threads(threads, || decompose(&x, Method::CoarseToFine, &p))
                            .expect("decomposes")
                            .systematic;
                });
                best[0][threads - 1] = best[0][threads - 1].min(v);
                best[1][threads - 1] = best[1][threads - 1].min(c);
            }
        }
        let differ = systematic[0]
            .iter()
            .zip(&systematic[1])
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count();
        let max_diff = systematic[0]
            .iter()
            .zip(&systematic[1])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!(
            "{{\"n\": {n}, \"vmd_one_s\": {:.6}, \"vmd_two_s\": {:.6}, \"vmd_one_over_two\": {:.3}, \"c2f_one_s\": {:.6}, \"c2f_two_s\": {:.6}, \"c2f_one_over_two\": {:.3}, \"systematic_samples_differing\": {differ}, \"systematic_max_diff_mm\": {max_diff:e}}}",
            best[0][0],
            best[0][1],
            best[0][0] / best[0][1],
            best[1][0],
            best[1][1],
            best[1][0] / best[1][1],
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = args
        .iter()
        .position(|a| a == "--signals")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let sizes: Vec<usize> = match args.iter().position(|a| a == "--sizes") {
        Some(i) => args[i + 1..].iter().map_while(|s| s.parse().ok()).collect(),
        None => vec![2025, 20_000, 250_000],
    };
    let reps_arg: Option<usize> = args
        .iter()
        .position(|a| a == "--reps")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok());
    if let Some(out) = args
        .iter()
        .position(|a| a == "--write-signals")
        .and_then(|i| args.get(i + 1))
    {
        std::fs::create_dir_all(out).expect("signal folder");
        for &n in &sizes {
            let text = serde_json::to_string(&paper_signal(n)).expect("numbers encode");
            std::fs::write(format!("{out}/signal_{n}.json"), text).expect("signal file written");
        }
        return;
    }
    if args.iter().any(|a| a == "--split") {
        split(&sizes, reps_arg.unwrap_or(20));
        return;
    }
    let rt = tokio::runtime::Runtime::new().expect("tokio runtime");
    let tmp = tempfile::tempdir().expect("temp dir");
    let config = truecut::config::Config::new(
        "127.0.0.1:0".parse().expect("address"),
        tmp.path().to_path_buf(),
    );
    let server = rt
        .block_on(truecut::server::start(&config))
        .expect("server starts");
    let base = format!("http://{}", server.addr());
    for n in sizes {
        let x: Vec<f64> = match &dir {
            Some(d) => {
                let text = std::fs::read_to_string(format!("{d}/signal_{n}.json"))
                    .expect("signal file from bench/peers_decompose.py");
                serde_json::from_str(&text).expect("a JSON array of numbers")
            }
            None => paper_signal(n),
        };
        let reps = reps_arg.unwrap_or(match n {
            0..=2025 => 15,
            2026..=20_000 => 5,
            _ => 2,
        });
        let default = DecomposeParams::default();
        let paper = DecomposeParams {
            refine: false,
            ..Default::default()
        };
        let mut sys_default = Vec::new();
        let mut sys_stages = Vec::new();
        let mut iterations = 0;
        let c2f = time(reps, || {
            let d = decompose(&x, Method::CoarseToFine, &default).expect("decomposes");
            iterations = d.components.stages.as_ref().map_or(0, |s| s.vmd_iterations);
            sys_default = d.systematic;
        });
        let stages = time(reps, || {
            sys_stages = decompose(&x, Method::CoarseToFine, &paper)
                .expect("decomposes")
                .systematic;
        });
        let tr = truth(n);
        let (a, b) = (accuracy(&sys_default, &tr), accuracy(&sys_stages, &tr));
        let vmd_s = time(reps, || {
            decompose(&x, Method::Vmd, &default).expect("decomposes");
        });
        let body = serde_json::json!({ "signal": x }).to_string();
        let http_s = http(&rt, &base, &body, reps);
        let prof = profile(&x, &body, reps);
        let prof: Vec<String> = prof
            .iter()
            .map(|(k, v)| format!("\"{k}\": {v:.3}"))
            .collect();
        println!(
            "{{\"n\": {n}, \"coarse_to_fine_s\": {c2f:.6}, \"stages_1_4_s\": {stages:.6}, \"vmd_s\": {vmd_s:.6}, \"http_s\": {http_s:.6}, \"vmd_iterations\": {iterations}, \"default_over_stages\": {:.3}, \"default_r_max_mean\": [{:.6}, {:.6}, {:.6}], \"stages_r_max_mean\": [{:.6}, {:.6}, {:.6}], \"profile_ms\": {{{}}}}}",
            c2f / stages,
            a[0],
            a[1],
            a[2],
            b[0],
            b[1],
            b[2],
            prof.join(", ")
        );
    }
    drop(server);
}
