//! Discrete wavelet transform (Daubechies and symlet families), multilevel decomposition and
//! reconstruction, and soft-threshold denoising.
//!
//! Written here (no crate): the Rust wavelet crates are partial or unmaintained (DESIGN.md).
//! The filters are computed from Daubechies' spectral factorisation instead of being typed in,
//! so db1..db10 and sym2..sym10 come from one formula; the conformance tests compare them with
//! PyWavelets to 1e-10.
//!
//! Boundary mode: half-sample symmetric extension (PyWavelets `mode='symmetric'`), so the
//! coefficient lengths and values agree with `pywt.wavedec(x, w, mode='symmetric')`.
//!
//! Files: `filters` (the filter banks), `dwt` (one level and multilevel transforms, the
//! level rule of PyWavelets), `denoise` (thresholding and the noise-level rule).

mod denoise;
mod dwt;
mod filters;
#[cfg(test)]
mod tests;

pub(crate) use denoise::median_abs;
pub use denoise::{Denoised, LevelRule, denoise, noise_level, soft_threshold};
pub use dwt::{dwt, idwt, max_level, wavedec, waverec};
pub use filters::Wavelet;
