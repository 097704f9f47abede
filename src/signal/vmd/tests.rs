//! Tests of VMD: decompositions, parameter checks, stopping rules, the f32 path against the
//! f64 one, and the fast sweeps against a naive reference sweep.

use super::iteration::{admm, admm_on, threads_for};
use super::sweep::{BLOCK, Kernel, Real, Sums, kernel_f32, kernel_f64, sweep_generic};
use super::*;
use realfft::RealFftPlanner;

#[test]
fn separates_three_tones() {
    let x: Vec<f64> = (0..512)
        .map(|k| {
            let t = k as f64;
            (2.0 * std::f64::consts::PI * 0.02 * t).cos()
                + 0.5 * (2.0 * std::f64::consts::PI * 0.12 * t).cos()
        })
        .collect();
    let r = vmd(
        &x,
        &VmdParams {
            k: Some(2),
            ..Default::default()
        },
    )
    .unwrap();
    assert!((r.omega[0] - 0.02).abs() < 2e-3, "{:?}", r.omega);
    assert!((r.omega[1] - 0.12).abs() < 2e-3, "{:?}", r.omega);
    assert_eq!(r.modes[0].len(), 512);
}

#[test]
fn odd_length_keeps_every_sample() {
    let x: Vec<f64> = (0..255).map(|k| (0.1 * k as f64).sin()).collect();
    let r = vmd(
        &x,
        &VmdParams {
            k: Some(1),
            alpha: 1.0,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(r.modes[0].len(), 255);
    let err = x
        .iter()
        .zip(&r.modes[0])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 5e-3, "{err}");
}

#[test]
fn rejects_bad_params_and_input() {
    let x = vec![1.0; 16];
    assert!(
        vmd(
            &x,
            &VmdParams {
                alpha: -1.0,
                ..Default::default()
            }
        )
        .is_err()
    );
    assert!(
        vmd(
            &x,
            &VmdParams {
                k: Some(0),
                ..Default::default()
            }
        )
        .is_err()
    );
    assert!(vmd(&[1.0, f64::NAN, 2.0, 3.0], &VmdParams::default()).is_err());
    assert!(vmd(&[1.0, 2.0], &VmdParams::default()).is_err());
}

#[test]
fn relative_convergence_is_scale_free_absolute_is_not() {
    let x: Vec<f64> = (0..600)
        .map(|k| {
            let t = k as f64;
            (2.0 * std::f64::consts::PI * 0.03 * t).sin()
                + 0.3 * (2.0 * std::f64::consts::PI * 0.2 * t).sin()
        })
        .collect();
    let big: Vec<f64> = x.iter().map(|v| v * 1000.0).collect();
    let run = |x: &[f64], convergence| {
        vmd(
            x,
            &VmdParams {
                k: Some(2),
                tol: 1e-6,
                convergence,
                ..Default::default()
            },
        )
        .unwrap()
    };
    let (r1, r2) = (
        run(&x, Convergence::Relative),
        run(&big, Convergence::Relative),
    );
    assert_eq!(r1.iterations, r2.iterations);
    assert!(r1.u_diff < 1e-6 && r1.iterations < 499, "{}", r1.iterations);
    let (a1, a2) = (
        run(&x, Convergence::Absolute),
        run(&big, Convergence::Absolute),
    );
    assert!(
        a2.iterations > a1.iterations,
        "{} {}",
        a1.iterations,
        a2.iterations
    );
    for (p, q) in r1.omega.iter().zip(&a1.omega) {
        assert!((p - q).abs() < 1e-3, "{:?} {:?}", r1.omega, a1.omega);
    }
}

/// |X(b)|² and b/n (cycles/sample) of the one-sided spectrum of `x` (bins 0..n/2): the
/// iteration's inputs for a signal taken as it is (no mirroring).
fn one_sided_power(x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(n);
    let mut buf = x.to_vec();
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut buf, &mut spec).unwrap();
    let m = n / 2;
    let power = spec[..m].iter().map(|c| c.norm_sqr()).collect();
    let freqs = (0..m).map(|b| b as f64 / n as f64).collect();
    (power, freqs)
}

#[test]
fn f32_iteration_matches_f64() {
    // The f32 path (long spectra) against the f64 one on the same input: modes to 1e-6
    // of the signal's amplitude after 40 iterations.
    let n = 8192;
    let x: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64;
            0.04 * (2.0 * std::f64::consts::PI * 0.004 * t).sin()
                + 0.01 * (2.0 * std::f64::consts::PI * 0.1 * t).cos()
                + 0.005 * ((k * 7919 % 1000) as f64 / 500.0 - 1.0)
        })
        .collect();
    let (power, freqs) = one_sided_power(&x);
    let p = VmdParams {
        k: Some(4),
        max_iter: 41,
        tol: 1e-300,
        ..Default::default()
    };
    let mut om64: Vec<f64> = (0..4).map(|k| 0.125 * k as f64).collect();
    let mut om32 = om64.clone();
    let (c64, _, _) = admm::<f64>(kernel_f64, &power, &freqs, &mut om64, &p);
    let (c32, _, _) = admm::<f32>(kernel_f32, &power, &freqs, &mut om32, &p);
    for (a, b) in om64.iter().zip(&om32) {
        assert!((a - b).abs() < 1e-6, "{om64:?} {om32:?}");
    }
    for (a, b) in c64.iter().zip(&c32) {
        let d = a
            .iter()
            .zip(b)
            .map(|(u, v)| (u - v).abs())
            .fold(0.0, f64::max);
        assert!(d < 1e-5, "coefficient difference {d}");
    }
}

#[test]
fn instantaneous_frequency_of_a_tone() {
    let x: Vec<f64> = (0..1000)
        .map(|k| (2.0 * std::f64::consts::PI * 0.05 * k as f64).sin())
        .collect();
    assert!((mean_instantaneous_frequency(&x) - 0.05).abs() < 1e-3);
}

/// The sweep written the obvious way: bin by bin, modes in order (Gauss-Seidel), the sum of
/// the other modes taken afresh instead of a running total, f64 throughout. Returns the per-mode
/// (Σν|û_k|², Σ|û_k|², Σ|Δû_k|²). The slow oracle of every sweep kernel.
fn reference_sweep<C: Real>(
    c: &mut [Vec<C>],
    power: &[C],
    target: Option<&[C]>,
    freqs: &[C],
    omega: &[f64],
    alpha: f64,
) -> [Vec<f64>; 3] {
    let k_modes = omega.len();
    let mut sums = [vec![0.0; k_modes], vec![0.0; k_modes], vec![0.0; k_modes]];
    for b in 0..power.len() {
        let (p, nu) = (power[b].to64(), freqs[b].to64());
        let tg = target.map_or(1.0, |t| t[b].to64());
        for k in 0..k_modes {
            let others: f64 = (0..k_modes)
                .filter(|&i| i != k)
                .map(|i| c[i][b].to64())
                .sum();
            let old = c[k][b].to64();
            let new = (tg - others) / (1.0 + alpha * (nu - omega[k]).powi(2));
            sums[0][k] += nu * new * new * p;
            sums[1][k] += new * new * p;
            sums[2][k] += (new - old) * (new - old) * p;
            c[k][b] = C::from64(new);
        }
    }
    sums
}

/// A spectrum of 2 blocks and 13 bins (so every kernel has full blocks, a short block and
/// bins past the last full register), K = 3 modes from a non-zero start, with and without
/// a target; returns (c, power, target, freqs, omega).
#[allow(clippy::type_complexity)]
fn sweep_case<C: Real>() -> (Vec<Vec<C>>, Vec<C>, Vec<C>, Vec<C>, Vec<f64>) {
    let m = 2 * BLOCK + 13;
    let unit = |i: usize, salt: usize| ((i * 7919 + salt * 104_729) % 1000) as f64 / 1000.0;
    let c = (0..3)
        .map(|k| (0..m).map(|b| C::from64(0.5 * unit(b, k))).collect())
        .collect();
    let power = (0..m).map(|b| C::from64(0.1 + 3.0 * unit(b, 7))).collect();
    let target = (0..m).map(|b| C::from64(0.8 + 0.4 * unit(b, 9))).collect();
    let freqs = (0..m)
        .map(|b| C::from64(b as f64 / (2 * m) as f64))
        .collect();
    (c, power, target, freqs, vec![0.01, 0.15, 0.37])
}

/// Runs `kernel` (with and without a target, three sweeps in a row) against
/// [`reference_sweep`]: coefficients to `tol_c`, sums to `tol_s`
/// relative (Σ|Δû_k|² to 100·`tol_s`: it is a sum of squared small differences, so storage
/// rounding of c weighs more in it).
fn check_kernel_against_reference<C: Real>(kernel: Kernel<C>, tol_c: f64, tol_s: f64) {
    let (c0, power, target, freqs, omega) = sweep_case::<C>();
    {
        for tgt in [None, Some(target.as_slice())] {
            let (mut fast, mut slow) = (c0.clone(), c0.clone());
            for _ in 0..3 {
                let mut got = Sums::new(omega.len());
                let mut cs: Vec<&mut [C]> = fast.iter_mut().map(|v| v.as_mut_slice()).collect();
                kernel(&mut cs, &power, tgt, &freqs, &omega, 2000.0, &mut got);
                let want = reference_sweep(&mut slow, &power, tgt, &freqs, &omega, 2000.0);
                for (name, g, w, tol) in [
                    ("num", &got.num, &want[0], tol_s),
                    ("den", &got.den, &want[1], tol_s),
                    ("dif", &got.dif, &want[2], 100.0 * tol_s),
                ] {
                    for (a, b) in g.iter().zip(w) {
                        assert!(
                            (a - b).abs() <= tol * b.abs().max(1e-300),
                            "{name} {a} vs {b}"
                        );
                    }
                }
                let d = fast
                    .iter()
                    .flatten()
                    .zip(slow.iter().flatten())
                    .map(|(u, v)| (u.to64() - v.to64()).abs())
                    .fold(0.0, f64::max);
                assert!(d <= tol_c, "coefficient difference {d}");
            }
        }
    }
}

#[test]
fn kernel_f64_matches_reference_sweep() {
    check_kernel_against_reference::<f64>(kernel_f64, 1e-13, 1e-11);
}

#[test]
fn kernel_f32_matches_reference_sweep() {
    check_kernel_against_reference::<f32>(kernel_f32, 2e-6, 1e-5);
}

#[test]
fn portable_sweep_matches_reference_sweep() {
    check_kernel_against_reference::<f64>(sweep_generic::<f64>, 1e-13, 1e-11);
    check_kernel_against_reference::<f32>(sweep_generic::<f32>, 2e-6, 1e-5);
}

/// Chen et al. 2024's eq. 23 signal (sampled every 0.01) plus a deterministic pseudo-noise
/// of 5 µm, `n` samples, mm.
fn paper_signal(n: usize) -> Vec<f64> {
    let mut state = 12345u64;
    (0..n)
        .map(|k| {
            let t = 1.0 + 0.01 * k as f64;
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            0.04 * ((1.6 * std::f64::consts::PI * t).sin()
                + (0.05 * std::f64::consts::PI * t).cos()
                + 4.0 * (-3.0 * t).exp())
                + 0.01 * (u - 0.5)
        })
        .collect()
}

/// Asserts `a` and `b` are the same bits, value by value.
fn same_bits(what: &str, a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    if let Some(i) = (0..a.len()).find(|&i| a[i].to_bits() != b[i].to_bits()) {
        panic!("{what}[{i}]: {:e} vs {:e}", a[i], b[i]);
    }
}

/// The two-thread lockstep iteration (long spectra on two cores) against the single-threaded
/// one on the same input, f64 and f32, with and without a dual step (τ): the same iteration
/// count and the same bits of every coefficient, ω and the stopping measure (issue 25: the
/// halves' per-mode sums are added in the same order on one thread or two). Runs on two
/// threads whatever the machine.
#[test]
fn split_iteration_is_bit_identical_to_single_thread() {
    let (power, freqs) = one_sided_power(&paper_signal(4050));
    fn check<C: Real>(kernel: Kernel<C>, power: &[f64], freqs: &[f64], tau: f64) {
        let p = VmdParams {
            tau,
            ..Default::default()
        };
        let om0: Vec<f64> = (0..7).map(|k| 0.5 / 7.0 * k as f64).collect();
        let (mut om1, mut om2) = (om0.clone(), om0);
        let (c1, it1, d1) = admm_on::<C>(kernel, power, freqs, &mut om1, &p, 1);
        let (c2, it2, d2) = admm_on::<C>(kernel, power, freqs, &mut om2, &p, 2);
        assert_eq!(it1, it2, "iterations (tau {tau})");
        assert!(it1 > 50, "stopped after {it1}");
        assert_eq!(d1.to_bits(), d2.to_bits(), "{d1} vs {d2} (tau {tau})");
        same_bits("omega", &om1, &om2);
        for (k, (a, b)) in c1.iter().zip(&c2).enumerate() {
            same_bits(&format!("c_{k} (tau {tau})"), a, b);
        }
    }
    for tau in [0.0, 0.1] {
        check::<f64>(kernel_f64, &power, &freqs, tau);
        check::<f32>(kernel_f32, &power, &freqs, tau);
    }
}

/// [`vmd`] pinned to one thread and to two ([`with_threads`]) at 2,025, 20,000 and 40,000
/// samples (f32 and split from 1,024 bins): every mode sample, ω, the
/// iteration count and the stopping measure are the same bits.
#[test]
fn vmd_is_bit_identical_on_one_thread_or_two() {
    for n in [2025, 20_000, 40_000] {
        let x = paper_signal(n);
        let p = VmdParams {
            max_iter: if n > 20_000 { 120 } else { 500 },
            ..Default::default()
        };
        let one = with_threads(1, || vmd(&x, &p)).unwrap();
        let two = with_threads(2, || vmd(&x, &p)).unwrap();
        assert_eq!(one.iterations, two.iterations, "n = {n}");
        assert_eq!(one.u_diff.to_bits(), two.u_diff.to_bits(), "n = {n}");
        same_bits(&format!("omega (n = {n})"), &one.omega, &two.omega);
        for (k, (a, b)) in one.modes.iter().zip(&two.modes).enumerate() {
            same_bits(&format!("mode {k} (n = {n})"), a, b);
        }
    }
}

/// Issue 25 item 7: the iteration splits only when a second thread would find a free core:
/// never below 1,024 bins, never while every core is taken by the process's busy threads
/// (here: as many threads as cores holding `numeric::parallel::busy`), and as pinned by
/// [`with_threads`] whatever the load.
#[test]
fn splits_only_when_a_core_is_free() {
    use crate::numeric::parallel;
    assert_eq!(threads_for(512), 1);
    assert_eq!(with_threads(2, || threads_for(4096)), 2);
    assert_eq!(with_threads(1, || threads_for(4096)), 1);
    let cores = parallel::resolve_threads(0);
    let (entered, release) = (
        std::sync::Barrier::new(cores + 1),
        std::sync::Barrier::new(cores + 1),
    );
    let seen = std::thread::scope(|s| {
        for _ in 0..cores {
            s.spawn(|| {
                let _busy = parallel::busy();
                entered.wait();
                release.wait();
            });
        }
        entered.wait();
        let seen = (threads_for(4096), parallel::core_free());
        release.wait();
        seen
    });
    assert_eq!(seen, (1, false), "{cores} busy threads on {cores} cores");
}
