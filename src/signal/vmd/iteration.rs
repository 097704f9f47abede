//! The ADMM loop of VMD in coefficient form and its split over two threads: the sweeps of
//! one iteration, the per-mode sums formed in a fixed order (so one thread and two give the
//! same bits), the new centre frequencies, the dual step and the stopping measure.
//!
//! Written here (no crate): vmd-rs is an unreviewed port (DESIGN.md). Each iteration's pass
//! over the spectrum is in [`super::sweep`]; the transforms around the loop in
//! [`super::admm`].

use super::admm::{Convergence, VmdParams};
use super::sweep::{Kernel, Real, Sums};
use crate::numeric::parallel::{self, Lockstep};
use std::cell::Cell;

/// Spectra at least this long (bins; signals of at least this many samples) are iterated by
/// two threads in lockstep (see [`admm`]) when the machine has two cores. One sweep of 1,024
/// bins and 7 modes is a few microseconds, against one thread start per decomposition and one
/// exchange per iteration. Measured on this project's 2-core Zen 3 machine (2,025 bins, K = 7,
/// 190 iterations, 200 runs each, interleaved): best 2.29 → 1.52 ms, median 2.5–3.0 → 2.1–2.6
/// ms.
const PARALLEL_MIN_BINS: usize = 1_024;

/// One piece of the bins (all, or a half): the coefficient slices c_k, |f̂|², frequencies, and the
/// target 1 − l/2 with the dual l (τ ≠ 0 only).
struct Bins<'a, C> {
    c: Vec<&'a mut [C]>,
    power: &'a [C],
    freqs: &'a [C],
    target: Option<(&'a mut [C], &'a mut [f64])>,
}

/// The ADMM iteration of [`super::vmd`] in coefficient form. Every update multiplies f̂(b) by a
/// real number, so from û = 0 and λ̂ = 0 every iterate is û_k(b) = c_k(b)·f̂(b) and
/// λ̂(b) = l(b)·f̂(b) with real c_k and l: the iteration runs on the c_k (half the memory
/// of complex modes), weighted by `power` = |f̂(b)|² in the sums. Updates `omega`; returns
/// the c_k (as f64), the iteration count and the last convergence measure.
///
/// From [`PARALLEL_MIN_BINS`] bins on two cores, the two halves of the bins ([`halves`]) are
/// iterated by two threads in lockstep ([`Lockstep`]): every bin's update needs only that
/// bin and ω, so each thread sweeps its half, the two per-mode sums are exchanged and both
/// threads compute the same ω and stopping measure from sums(lower half) + sums(upper half).
/// One thread sweeps the same two halves one after the other and adds their sums in the
/// same order, so the answer is the same bits on one thread or two (checked by
/// `split_iteration_is_bit_identical_to_single_thread`).
///
/// Only a run that starts while a core is free splits ([`parallel::core_free`]: no other
/// thread of the process busy with numeric work, whatever its kind, and fewer threads
/// runnable on the machine than cores). When the service's workers are all busy, or another
/// process holds the other core, a second thread per run only adds waiting at the exchange:
/// its partner waits for a time slice. Measured with `bench/overload.sh` (2 workers, 8-64
/// connections; BENCHMARKS.md): goodput 76-78/s before the split, 50-58/s splitting always,
/// 64-74/s splitting when no other VMD runs; and with a CPU-bound process on the other core
/// (BENCHMARKS.md, issue 25 item 7). A load that comes after the start is met by the
/// exchange's parking wait ([`Lockstep`]). That choice depends on the load, hence the fixed
/// reduction order above: the load decides the speed, never the bits.
pub(super) fn admm<C: Real>(
    kernel: Kernel<C>,
    power: &[f64],
    freqs: &[f64],
    omega: &mut [f64],
    params: &VmdParams,
) -> (Vec<Vec<f64>>, usize, f64) {
    // This thread is busy (once, if its caller already said so) while the iteration runs.
    let _busy = parallel::busy();
    admm_on(
        kernel,
        power,
        freqs,
        omega,
        params,
        threads_for(power.len()),
    )
}

/// Threads for an iteration over `bins` bins started now: as pinned by [`with_threads`], else
/// 2 from [`PARALLEL_MIN_BINS`] bins when a core is free ([`parallel::core_free`]), else 1.
pub(super) fn threads_for(bins: usize) -> usize {
    match PINNED.with(Cell::get) {
        Some(t) => t,
        None if bins >= PARALLEL_MIN_BINS && parallel::core_free() => 2,
        None => 1,
    }
}

thread_local! {
    /// Threads every VMD iteration started on this thread uses ([`with_threads`]); `None`:
    /// chosen by [`admm`] from the load.
    static PINNED: Cell<Option<usize>> = const { Cell::new(None) };
}

/// Runs `f` with every VMD iteration it starts on the calling thread on `threads` threads (1:
/// never split; 2: split from `PARALLEL_MIN_BINS` bins whatever else runs) instead of the
/// load-dependent choice of `admm`. The answer is the same bits either way; this is for
/// the tests that check so and for benchmarks that time both paths. Work `f` hands to other
/// threads (coarse-to-fine's EMD and refinement) runs no VMD, so is unaffected.
pub fn with_threads<R>(threads: usize, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<usize>);
    impl Drop for Restore {
        fn drop(&mut self) {
            PINNED.with(|p| p.set(self.0));
        }
    }
    let _restore = Restore(PINNED.with(|p| p.replace(Some(threads.clamp(1, 2)))));
    f()
}

/// Where the bins of a spectrum of `m` bins are cut into the two halves whose per-mode sums
/// are formed separately and added lower + upper ([`admm`]): `None` (one piece) below
/// [`PARALLEL_MIN_BINS`]; else near the middle, on a multiple of 8 bins (one f32 register).
/// A function of `m` alone, never of the thread count: that is what makes one thread and two
/// add in the same order.
fn halves(m: usize) -> Option<usize> {
    (m >= PARALLEL_MIN_BINS).then_some(m / 2 / 8 * 8)
}

/// [`admm`] on `threads` threads (1, or 2 in lockstep; 2 only from [`PARALLEL_MIN_BINS`]
/// bins). The same bits for either count.
pub(super) fn admm_on<C: Real>(
    kernel: Kernel<C>,
    power: &[f64],
    freqs: &[f64],
    omega: &mut [f64],
    params: &VmdParams,
    threads: usize,
) -> (Vec<Vec<f64>>, usize, f64) {
    let m = power.len();
    let t = 2 * m;
    let k_modes = omega.len();
    let power: Vec<C> = power.iter().map(|&v| C::from64(v)).collect();
    let freqs: Vec<C> = freqs.iter().map(|&v| C::from64(v)).collect();
    let mut dual = vec![0.0; m];
    let mut target: Option<Vec<C>> = (params.tau != 0.0).then(|| vec![C::from64(1.0); m]);
    let mut c = vec![vec![C::default(); m]; k_modes];
    let Some(mid) = halves(m) else {
        let whole = Bins {
            c: c.iter_mut().map(|v| v.as_mut_slice()).collect(),
            power: &power,
            freqs: &freqs,
            target: target.as_deref_mut().map(|tc| (tc, dual.as_mut_slice())),
        };
        let (iterations, u_diff) = iterate(kernel, vec![whole], omega, t, params, None);
        return (to64(c), iterations, u_diff);
    };
    let (ca, cb): (Vec<&mut [C]>, Vec<&mut [C]>) =
        c.iter_mut().map(|v| v.split_at_mut(mid)).unzip();
    let (targets_a, targets_b) = match target.as_deref_mut() {
        Some(tc) => {
            let (ta, tb) = tc.split_at_mut(mid);
            let (da, db) = dual.split_at_mut(mid);
            (Some((ta, da)), Some((tb, db)))
        }
        None => (None, None),
    };
    let lower = Bins {
        c: ca,
        power: &power[..mid],
        freqs: &freqs[..mid],
        target: targets_a,
    };
    let upper = Bins {
        c: cb,
        power: &power[mid..],
        freqs: &freqs[mid..],
        target: targets_b,
    };
    let (iterations, u_diff) = if threads < 2 {
        iterate(kernel, vec![lower, upper], omega, t, params, None)
    } else {
        let lockstep = Lockstep::new();
        let mut omega_b = omega.to_vec();
        let (b, a) = parallel::join(
            || {
                iterate(
                    kernel,
                    vec![upper],
                    &mut omega_b,
                    t,
                    params,
                    Some((&lockstep, 1)),
                )
            },
            || iterate(kernel, vec![lower], omega, t, params, Some((&lockstep, 0))),
        );
        let b = b.unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        debug_assert!(b.0 == a.0 && omega_b == omega, "the two sides agree");
        a
    };
    (to64(c), iterations, u_diff)
}

/// The coefficients as f64.
fn to64<C: Real>(c: Vec<Vec<C>>) -> Vec<Vec<f64>> {
    c.into_iter()
        .map(|v| v.into_iter().map(Real::to64).collect())
        .collect()
}

/// The iteration loop of [`admm_on`] over `pieces` of the bins, swept in order on this
/// thread: the whole spectrum, its two halves, or one half whose `lockstep` partner sweeps
/// the other. The per-mode sums of each piece are formed separately and added in piece order
/// (lower half first), so every arrangement adds the same numbers in the same order. Returns
/// the iteration count and the last convergence measure. `t` is the mirrored signal's length
/// T (the whole spectrum's, 2 × all bins).
fn iterate<C: Real>(
    kernel: Kernel<C>,
    mut pieces: Vec<Bins<'_, C>>,
    omega: &mut [f64],
    t: usize,
    params: &VmdParams,
    lockstep: Option<(&Lockstep<Sums>, usize)>,
) -> (usize, f64) {
    let k_modes = omega.len();
    let guard = lockstep.map(|(l, _)| l.guard());
    let mut iterations = 0;
    let mut u_diff = f64::INFINITY;
    // ‖û_k^n‖² of the iterate before the sweep (the sweep returns that of the new one).
    let mut prev_den = vec![0.0; k_modes];
    while iterations < params.max_iter.saturating_sub(1) && u_diff > params.tol {
        // A stopped job ends here; a lockstep partner waiting at the exchange sees this
        // side's guard abandon it and stops too.
        crate::numeric::stop::check();
        let mut parts: Vec<Sums> = pieces
            .iter_mut()
            .map(|bins| {
                let mut mine = Sums::new(k_modes);
                kernel(
                    &mut bins.c,
                    bins.power,
                    bins.target.as_ref().map(|(tc, _)| &**tc),
                    bins.freqs,
                    omega,
                    params.alpha,
                    &mut mine,
                );
                mine
            })
            .collect();
        if let Some((l, side)) = lockstep {
            let mine = parts.pop().expect("one piece per lockstep side");
            let (lower, upper) = l.exchange(side, iterations, mine);
            parts = vec![lower, upper];
        }
        let mut sums = Sums::new(k_modes);
        for part in &parts {
            sums.add(part);
        }
        for (k, om) in omega.iter_mut().enumerate() {
            if !(params.dc && k == 0) && sums.den[k] > 0.0 {
                *om = sums.num[k] / sums.den[k];
            }
        }
        for bins in pieces.iter_mut() {
            if let Some((tc, dual)) = bins.target.as_mut() {
                for b in 0..tc.len() {
                    let s: f64 = (0..k_modes).map(|k| bins.c[k][b].to64()).sum();
                    dual[b] += params.tau * (s - 1.0);
                    tc[b] = C::from64(1.0 - 0.5 * dual[b]);
                }
            }
        }
        iterations += 1;
        u_diff = match params.convergence {
            Convergence::Absolute => f64::EPSILON + sums.dif.iter().sum::<f64>() / t as f64,
            // A mode that was zero has not converged unless it is still zero.
            Convergence::Relative => sums
                .dif
                .iter()
                .zip(&prev_den)
                .map(|(&d, &e)| match (d > 0.0, e > 0.0) {
                    (_, true) => d / e,
                    (false, false) => 0.0,
                    (true, false) => f64::INFINITY,
                })
                .sum(),
        };
        prev_den = sums.den;
    }
    if let Some(g) = guard {
        g.leave();
    }
    (iterations, u_diff)
}
