//! Real-FFT plans kept per thread: planning a mixed-radix transform (its twiddle tables,
//! one sin/cos per entry, and the radix search) costs as much as several transforms of
//! the same length, and every decomposition asks for the same few lengths again (the VMD
//! mirror 2n, the refinement's DCT 2n, the carrier periodogram 4n).
//!
//! Written here (no crate): a `thread_local!` around realfft's own planner, whose cache
//! then lives as long as the worker thread instead of one call.

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::cell::RefCell;
use std::sync::Arc;

thread_local! {
    static PLANNER: RefCell<RealFftPlanner<f64>> = RefCell::new(RealFftPlanner::new());
}

/// The forward real-to-complex FFT of length `len` (unnormalised), from this thread's cache.
pub(crate) fn forward(len: usize) -> Arc<dyn RealToComplex<f64>> {
    PLANNER.with(|p| p.borrow_mut().plan_fft_forward(len))
}

/// The inverse complex-to-real FFT of length `len` (unnormalised), from this thread's cache.
pub(crate) fn inverse(len: usize) -> Arc<dyn ComplexToReal<f64>> {
    PLANNER.with(|p| p.borrow_mut().plan_fft_inverse(len))
}

#[cfg(test)]
mod tests;
