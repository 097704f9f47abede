//! Variational mode decomposition (Dragomiretskiy & Zosso 2014), ADMM in the frequency domain.
//!
//! Written here (no crate): vmd-rs is an unreviewed port (DESIGN.md). The iteration is the
//! published one (Chen et al. 2024 eqs. 5–8); it is arranged so that one pass over the spectrum
//! updates all K modes of a bin (mode k's Wiener filter uses only bin-local sums and the
//! previous ω_k, so the bin loop and the mode loop commute), which keeps the work in cache.
//!
//! Files: `admm` (parameters and their validation, the transforms, the automatic choice of
//! K), `iteration` (the ADMM loop and its split over two threads, same bits either way),
//! `sweep` (one pass over the spectrum: the portable kernel and one AVX2 kernel serving
//! f64 and f32) and `lanes` (the AVX2 register operations over the lane type).

mod admm;
mod iteration;
#[cfg(target_arch = "x86_64")]
mod lanes;
mod sweep;
#[cfg(test)]
mod tests;

pub use admm::{
    Convergence, F32_MIN_BINS, VmdParams, VmdResult, choose_k, mean_instantaneous_frequency, vmd,
};
pub use iteration::with_threads;
pub use sweep::kernel;
