//! VMD by ADMM (Dragomiretskiy & Zosso 2014, Algorithm 2): parameters and their validation,
//! the mirror extension and transforms around the iteration, and the automatic choice of K.
//!
//! Written here (no crate): vmd-rs is an unreviewed port (DESIGN.md). The iteration itself
//! (coefficient form, its split over two threads) is in [`super::iteration`], each
//! iteration's pass over the spectrum in [`super::sweep`].

use super::iteration::admm;
use super::sweep::{kernel_f32, kernel_f64};
use crate::signal::error::{Error, check_signal};
use rustfft::num_complex::Complex;
use serde::{Deserialize, Serialize};

/// VMD parameters (names as vmdpy / Zosso's MATLAB code).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VmdParams {
    /// Bandwidth penalty α (dimensionless; larger = narrower modes). Default 2000.
    pub alpha: f64,
    /// Dual ascent step τ (0 = noise-tolerant, no exact reconstruction). Default 0.
    pub tau: f64,
    /// Number of modes K, or `None` for the automatic choice ([`choose_k`]). Default 7
    /// (Chen et al. 2024's value for its 2,025-point signals).
    #[serde(rename = "K", alias = "k")]
    pub k: Option<usize>,
    /// Hold the first mode at ω = 0. Default false.
    #[serde(rename = "DC", alias = "dc")]
    pub dc: bool,
    /// ω initialisation: 0 = all zero, 1 = uniform ω_k = 0.5 k / K. Default 1.
    pub init: u8,
    /// Convergence tolerance ε of the stopping rule chosen by `convergence`. Default 1e-7.
    pub tol: f64,
    /// Stopping rule: `absolute` (default, as vmdpy) or `relative` (see [`Convergence`]).
    pub convergence: Convergence,
    /// Iteration cap (vmdpy's Niter). Default 500.
    pub max_iter: usize,
}

impl Default for VmdParams {
    fn default() -> Self {
        Self {
            alpha: 2000.0,
            tau: 0.0,
            k: Some(7),
            dc: false,
            init: 1,
            tol: 1e-7,
            convergence: Convergence::Absolute,
            max_iter: 500,
        }
    }
}

/// VMD stopping rule, with û_k the one-sided unnormalised DFT of mode k of the mirrored
/// signal (length T = 2n) and n the iteration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Convergence {
    /// Σ_k ‖û_k^{n+1} − û_k^n‖² / ‖û_k^n‖² < tol: the criterion as published
    /// (Dragomiretskiy & Zosso 2014, Algorithm 2; Chen et al. 2024 eq. 7). Dimensionless, so the
    /// same tol means the same precision at every length and amplitude.
    Relative,
    /// Σ_k ‖û_k^{n+1} − û_k^n‖² / T < tol (signal units²): what Zosso's MATLAB code and vmdpy
    /// test. With unnormalised transforms it grows ∝ T, so it tightens with the length and
    /// long signals stop at `max_iter` (250,000 samples: 499 iterations at tol 1e-7).
    #[default]
    Absolute,
}
impl VmdParams {
    /// Checks ranges; the sentence names the parameter.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |name, reason: &str| {
            Err(Error::BadParam {
                name,
                reason: reason.into(),
            })
        };
        if !(self.alpha.is_finite() && self.alpha > 0.0) {
            return bad("alpha", "must be a finite number > 0 (typical 500..20000)");
        }
        if !(self.tau.is_finite() && self.tau >= 0.0) {
            return bad("tau", "must be a finite number >= 0");
        }
        if let Some(k) = self.k {
            if !(1..=32).contains(&k) {
                return bad("K", "must be between 1 and 32");
            }
        }
        if self.init > 1 {
            return bad("init", "must be 0 (all zero) or 1 (uniform)");
        }
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return bad("tol", "must be a finite number > 0");
        }
        if self.max_iter == 0 || self.max_iter > 100_000 {
            return bad("max_iter", "must be between 1 and 100000");
        }
        Ok(())
    }
}

/// Spectra at least this long (bins; signals of at least this many samples) are iterated in
/// f32 (see [`vmd`]).
pub const F32_MIN_BINS: usize = 1_024;

/// Output of [`vmd`].
#[derive(Clone, Debug, Serialize)]
pub struct VmdResult {
    /// K modes, each as long as the input, lowest centre frequency first (init order).
    pub modes: Vec<Vec<f64>>,
    /// Final centre frequencies in cycles per sample (0 … 0.5).
    pub omega: Vec<f64>,
    /// ADMM iterations run (at most `max_iter`).
    pub iterations: usize,
    /// Last value of the convergence measure.
    pub u_diff: f64,
}

/// Decomposes `x` into K band-limited modes by VMD.
///
/// Formula (Chen et al. 2024 eqs. 5–8; Dragomiretskiy & Zosso 2014, Algorithm 2): on the one-sided
/// spectrum of the mirror-extended signal (length T = 2n), Gauss-Seidel updates
/// û_k ← (f̂ − Σ_{i≠k} û_i − λ̂/2) / (1 + α(ω − ω_k)²) (ω in cycles/sample, as vmdpy),
/// ω_k ← Σ ω|û_k|² / Σ |û_k|², λ̂ ← λ̂ + τ(Σ û_k − f̂), until the [`Convergence`] rule
/// holds (default `absolute` as vmdpy: Σ_k ‖û_k^{n+1} − û_k^n‖²/T < tol; `relative` as
/// published) or `max_iter`. Returns the last iterate (as the MATLAB reference; vmdpy
/// returns the one before, a 1e-5 mm difference on Chen et al. 2024's signal).
///
/// Arithmetic: the iteration runs on real coefficients c_k with û_k = c_k·f̂ (exact, see
/// `iteration::admm`), in f64 below [`F32_MIN_BINS`] bins and in f32 from there on (signals of at
/// least 1,024 samples: the sweep is bound by memory and division throughput, and f32
/// halves both; at 2,025 samples the iteration took 1.5× less time; the threshold was 16,384
/// until issue 25 item 7). Measured on Chen et al. 2024's signal at 250,000 samples: the f32 modes differ
/// from the f64 ones by at most 1.4e-8 mm (modes of rms 0.001-0.03 mm), and the same
/// iteration count and systematic error to 6 digits.
///
/// Mirror extension: [rev(x[..h]), x, rev(x[h..])] with h = ceil(n/2), so odd and even
/// lengths are both exact (vmdpy drops the last sample of odd-length input).
/// Known bad cases: with τ = 0 Σ modes ≠ x (the residual is part of the noise); modes can
/// merge for init = 1 when two components are closer than ~1/sqrt(α) cycles/sample.
pub fn vmd(x: &[f64], params: &VmdParams) -> Result<VmdResult, Error> {
    params.validate()?;
    check_signal("vmd", x, 4)?;
    let k_modes = params.k.unwrap_or(7);
    let n = x.len();
    let h = n.div_ceil(2);
    let t = 2 * n;
    let mut mirrored = Vec::with_capacity(t);
    mirrored.extend(x[..h].iter().rev());
    mirrored.extend_from_slice(x);
    mirrored.extend(x[h..].iter().rev());

    let fwd = crate::signal::fft::forward(t);
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut mirrored, &mut spec)
        .map_err(|e| Error::BadParam {
            name: "signal",
            reason: e.to_string(),
        })?;
    // One-sided: bins 0..T/2 (frequency b/T); the Nyquist bin is dropped as in the reference.
    let m = t / 2;
    let f_hat: Vec<Complex<f64>> = spec[..m].to_vec();
    let freqs: Vec<f64> = (0..m).map(|b| b as f64 / t as f64).collect();

    let mut omega: Vec<f64> = (0..k_modes)
        .map(|k| {
            if params.init == 1 {
                0.5 / k_modes as f64 * k as f64
            } else {
                0.0
            }
        })
        .collect();
    if params.dc {
        omega[0] = 0.0;
    }
    crate::numeric::stop::check();
    let power: Vec<f64> = f_hat.iter().map(|c| c.norm_sqr()).collect();
    let (c, iterations, u_diff) = if m >= F32_MIN_BINS {
        admm::<f32>(kernel_f32, &power, &freqs, &mut omega, params)
    } else {
        admm::<f64>(kernel_f64, &power, &freqs, &mut omega, params)
    };
    let u: Vec<Complex<f64>> = (0..m)
        .flat_map(|b| (0..k_modes).map(move |k| (b, k)))
        .map(|(b, k)| f_hat[b] * c[k][b])
        .collect();

    let inv = crate::signal::fft::inverse(t);
    let mut modes = Vec::with_capacity(k_modes);
    let mut buf = inv.make_input_vec();
    let mut out = inv.make_output_vec();
    for k in 0..k_modes {
        crate::numeric::stop::check();
        for b in 0..m {
            buf[b] = u[b * k_modes + k];
        }
        // The reference rebuilds a Hermitian spectrum whose DC bin keeps only its real part
        // and whose Nyquist bin is conj(û[T/2-1]); the real output depends on Re of both.
        buf[0] = Complex::new(buf[0].re, 0.0);
        buf[m] = Complex::new(u[(m - 1) * k_modes + k].re, 0.0);
        inv.process(&mut buf, &mut out)
            .map_err(|e| Error::BadParam {
                name: "signal",
                reason: e.to_string(),
            })?;
        modes.push(out[h..h + n].iter().map(|v| v / t as f64).collect());
    }
    Ok(VmdResult {
        modes,
        omega,
        iterations,
        u_diff,
    })
}

/// Mean instantaneous frequency of a mode in cycles/sample: the mean over samples of the
/// phase increment of its analytic signal (Hilbert transform by FFT) / 2π.
///
/// Reference: the instantaneous-frequency-mean method for choosing K (Chang et al. 2021,
/// cited as \[30\] in Chen et al. 2024). Known bad cases: a mode that is ~0 everywhere (returns 0).
pub fn mean_instantaneous_frequency(mode: &[f64]) -> f64 {
    let n = mode.len();
    if n < 3 {
        return 0.0;
    }
    let mut planner = rustfft::FftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let ifft = planner.plan_fft_inverse(n);
    let mut z: Vec<Complex<f64>> = mode.iter().map(|&v| Complex::new(v, 0.0)).collect();
    fft.process(&mut z);
    for (i, c) in z.iter_mut().enumerate() {
        let factor = if i == 0 || (n % 2 == 0 && i == n / 2) {
            1.0
        } else if i < n.div_ceil(2) {
            2.0
        } else {
            0.0
        };
        *c *= factor;
    }
    ifft.process(&mut z);
    let mut sum = 0.0;
    for w in z.windows(2) {
        let dphi = (w[1] * w[0].conj()).arg();
        sum += dphi;
    }
    (sum / (n - 1) as f64 / (2.0 * std::f64::consts::PI)).abs()
}

/// Automatic K by the instantaneous-frequency-mean method: for K = 2, 3, … up to `k_max`,
/// decompose and take the mean instantaneous frequency of each mode; the first K whose
/// highest mode's mean IF is lower than at K − 1 (the curve bends down: a new mode split an
/// existing band instead of finding a new one, i.e. over-decomposition) stops the search and
/// K − 1 is returned; `k_max` if it never bends.
///
/// Reference: Chen et al. 2024 §3.1 (K = 7 found this way for its 2,025-point signals) and
/// Chang et al. 2021. Known bad cases: costs up to k_max − 1 VMD runs; on clean signals of
/// a few pure tones the highest mode's IF can tie between K and K + 1 and the search stops
/// one or more modes early (the screening then still keeps every tone's mode).
pub fn choose_k(x: &[f64], params: &VmdParams, k_max: usize) -> Result<usize, Error> {
    let mut prev_top = -1.0;
    for k in 2..=k_max.max(2) {
        crate::numeric::stop::check();
        let p = VmdParams {
            k: Some(k),
            ..params.clone()
        };
        let r = vmd(x, &p)?;
        let top = r
            .modes
            .iter()
            .map(|m| mean_instantaneous_frequency(m))
            .fold(0.0, f64::max);
        if top < prev_top {
            return Ok(k - 1);
        }
        prev_top = top;
    }
    Ok(k_max.max(2))
}
