//! Real-FFT plans and per-length tables kept for the whole process: planning a mixed-radix
//! transform (its twiddle tables, one sin/cos per entry, and the radix search) costs as much
//! as several transforms of the same length, and every decomposition asks for the same few
//! lengths again (the VMD mirror 2n, the refinement's DCT 2n, the carrier periodogram 4n).
//! The same holds for the refinement smoother's per-length tables (the penalty's
//! eigenvalues, one cosine each, and the DCT's twiddles, one sine and cosine each): [`table`].
//!
//! Written here (no crate): a `Mutex` around realfft's own planner, whose cache then lives
//! as long as the process. It was a `thread_local!` until issue 41: the stages a
//! decomposition runs on a scoped second thread (EMD, the lone smoother) then planned again
//! on every call (at 2,025 samples 1.1 M of 38 M instructions per decomposition, callgrind).

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::sync::{Arc, Mutex, OnceLock};

/// The process's planner (its cache keeps every plan made).
fn planner() -> std::sync::MutexGuard<'static, RealFftPlanner<f64>> {
    static PLANNER: OnceLock<Mutex<RealFftPlanner<f64>>> = OnceLock::new();
    PLANNER
        .get_or_init(|| Mutex::new(RealFftPlanner::new()))
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The forward real-to-complex FFT of length `len` (unnormalised), from the process's cache.
pub(crate) fn forward(len: usize) -> Arc<dyn RealToComplex<f64>> {
    planner().plan_fft_forward(len)
}

/// The inverse complex-to-real FFT of length `len` (unnormalised), from the process's cache.
pub(crate) fn inverse(len: usize) -> Arc<dyn ComplexToReal<f64>> {
    planner().plan_fft_inverse(len)
}

/// Which per-length table [`table`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Table {
    /// `numeric::penalty::reflective_eigenvalues(n, d)`.
    Eigenvalues(usize),
    /// The DCT-II twiddles of `whittaker::dct_power`: cos and sin of −πk/(2n), interleaved.
    DctTwiddles,
    /// The Hann window 0.5 − 0.5 cos(2πt/n) of `carrier::strongest_line`.
    Hann,
}

/// Tables kept ([`table`]): the most recent few, so memory stays bounded whatever lengths
/// the requests bring (8 × 8 MB at the largest signal, 1,000,000 samples).
const TABLES_KEPT: usize = 8;

/// The table `kind` for length `n`, computed by `make` on the first call and then shared
/// (the same values, so the same bits, as computing it afresh).
pub(crate) fn table(kind: Table, n: usize, make: impl FnOnce() -> Vec<f64>) -> Arc<Vec<f64>> {
    type Kept = Vec<(Table, usize, Arc<Vec<f64>>)>;
    static TABLES: Mutex<Kept> = Mutex::new(Vec::new());
    let lock = || TABLES.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, _, t)) = lock().iter().find(|(k, m, _)| *k == kind && *m == n) {
        return t.clone();
    }
    let t = Arc::new(make());
    let mut kept = lock();
    if kept.len() >= TABLES_KEPT {
        kept.remove(0);
    }
    kept.push((kind, n, t.clone()));
    t
}

#[cfg(test)]
mod tests;
