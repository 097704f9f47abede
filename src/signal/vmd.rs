//! Variational mode decomposition (Dragomiretskiy & Zosso 2014), ADMM in the frequency domain.
//!
//! Written here (no crate): vmd-rs is an unreviewed port (DESIGN.md). The iteration is the
//! published one (paper 002 eqs. 5-8); it is arranged so that one pass over the spectrum
//! updates all K modes of a bin (mode k's Wiener filter uses only bin-local sums and the
//! previous ω_k, so the bin loop and the mode loop commute), which keeps the work in cache.

use super::error::{Error, check_signal};
use realfft::RealFftPlanner;
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
    /// (the paper's value for its 2,025-point signals).
    #[serde(rename = "K", alias = "k")]
    pub k: Option<usize>,
    /// Hold the first mode at ω = 0. Default false.
    #[serde(rename = "DC", alias = "dc")]
    pub dc: bool,
    /// ω initialisation: 0 = all zero, 1 = uniform ω_k = 0.5 k / K. Default 1.
    pub init: u8,
    /// Convergence tolerance on Σ_k ‖Δû_k‖²/T (absolute, in signal units²). Default 1e-7.
    pub tol: f64,
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
            max_iter: 500,
        }
    }
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

/// Spectra at least this long (bins) are swept by two threads.
const PARALLEL_MIN_BINS: usize = 32_768;

/// Bins per cache block of the sweep.
const BLOCK: usize = 512;

/// One ADMM iteration over all bins: updates every mode in place, adds Σν|û|² and Σ|û|² per
/// mode to `num`/`den`, returns Σ|Δû|². Splits the bins over `threads` threads.
#[allow(clippy::too_many_arguments)]
fn sweep(
    u_re: &mut [Vec<f64>],
    u_im: &mut [Vec<f64>],
    t_re: &[f64],
    t_im: &[f64],
    freqs: &[f64],
    omega: &[f64],
    alpha: f64,
    num: &mut [f64],
    den: &mut [f64],
    threads: usize,
) -> f64 {
    let m = t_re.len();
    if threads <= 1 {
        let mut re: Vec<&mut [f64]> = u_re.iter_mut().map(|v| v.as_mut_slice()).collect();
        let mut im: Vec<&mut [f64]> = u_im.iter_mut().map(|v| v.as_mut_slice()).collect();
        return sweep_range(&mut re, &mut im, t_re, t_im, freqs, omega, alpha, num, den);
    }
    let mid = m / 2;
    let (mut re_a, mut re_b): (Vec<&mut [f64]>, Vec<&mut [f64]>) =
        u_re.iter_mut().map(|v| v.split_at_mut(mid)).unzip();
    let (mut im_a, mut im_b): (Vec<&mut [f64]>, Vec<&mut [f64]>) =
        u_im.iter_mut().map(|v| v.split_at_mut(mid)).unzip();
    let k = omega.len();
    let (mut num_b, mut den_b) = (vec![0.0; k], vec![0.0; k]);
    let diff_b = std::thread::scope(|s| {
        let handle = s.spawn(|| {
            sweep_range(
                &mut re_b,
                &mut im_b,
                &t_re[mid..],
                &t_im[mid..],
                &freqs[mid..],
                omega,
                alpha,
                &mut num_b,
                &mut den_b,
            )
        });
        let diff_a = sweep_range(
            &mut re_a,
            &mut im_a,
            &t_re[..mid],
            &t_im[..mid],
            &freqs[..mid],
            omega,
            alpha,
            num,
            den,
        );
        diff_a + handle.join().expect("VMD sweep thread panicked")
    });
    for i in 0..k {
        num[i] += num_b[i];
        den[i] += den_b[i];
    }
    diff_b
}

/// [`sweep`] on one contiguous bin range, dispatching to an AVX2+FMA build when available.
#[allow(clippy::too_many_arguments)]
fn sweep_range(
    u_re: &mut [&mut [f64]],
    u_im: &mut [&mut [f64]],
    t_re: &[f64],
    t_im: &[f64],
    freqs: &[f64],
    omega: &[f64],
    alpha: f64,
    num: &mut [f64],
    den: &mut [f64],
) -> f64 {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports the features the function is compiled for.
            return unsafe { sweep_avx2(u_re, u_im, t_re, t_im, freqs, omega, alpha, num, den) };
        }
    }
    sweep_generic(u_re, u_im, t_re, t_im, freqs, omega, alpha, num, den)
}

/// The sweep kernel in AVX2+FMA intrinsics (4 bins per instruction); same arithmetic as
/// [`sweep_generic`] up to FMA rounding.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn sweep_avx2(
    u_re: &mut [&mut [f64]],
    u_im: &mut [&mut [f64]],
    t_re: &[f64],
    t_im: &[f64],
    freqs: &[f64],
    omega: &[f64],
    alpha: f64,
    num: &mut [f64],
    den: &mut [f64],
) -> f64 {
    use std::arch::x86_64::*;
    let m = t_re.len();
    let mut tot_re = [0.0; BLOCK];
    let mut tot_im = [0.0; BLOCK];
    let mut diff_s = 0.0;
    let one = _mm256_set1_pd(1.0);
    let va = _mm256_set1_pd(alpha);
    let mut vdiff = _mm256_setzero_pd();
    let mut start = 0;
    while start < m {
        let len = BLOCK.min(m - start);
        let end = start + len;
        tot_re[..len].fill(0.0);
        tot_im[..len].fill(0.0);
        for k in 0..omega.len() {
            for (t, v) in tot_re[..len].iter_mut().zip(&u_re[k][start..end]) {
                *t += v;
            }
            for (t, v) in tot_im[..len].iter_mut().zip(&u_im[k][start..end]) {
                *t += v;
            }
        }
        let full = len / 4 * 4;
        for (k, &om) in omega.iter().enumerate() {
            let vom = _mm256_set1_pd(om);
            let mut vnum = _mm256_setzero_pd();
            let mut vden = _mm256_setzero_pd();
            let ur = u_re[k][start..end].as_mut_ptr();
            let ui = u_im[k][start..end].as_mut_ptr();
            let tr = tot_re.as_mut_ptr();
            let ti = tot_im.as_mut_ptr();
            let fr = t_re[start..end].as_ptr();
            let fi = t_im[start..end].as_ptr();
            let nu = freqs[start..end].as_ptr();
            let mut i = 0;
            // SAFETY: i + 4 <= full <= len, and every pointer addresses at least len values.
            unsafe {
                while i < full {
                    let vnu = _mm256_loadu_pd(nu.add(i));
                    let d = _mm256_sub_pd(vnu, vom);
                    let w = _mm256_div_pd(one, _mm256_fmadd_pd(_mm256_mul_pd(va, d), d, one));
                    let vur = _mm256_loadu_pd(ur.add(i));
                    let vui = _mm256_loadu_pd(ui.add(i));
                    let or = _mm256_sub_pd(_mm256_loadu_pd(tr.add(i)), vur);
                    let oi = _mm256_sub_pd(_mm256_loadu_pd(ti.add(i)), vui);
                    let nr = _mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(fr.add(i)), or), w);
                    let ni = _mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(fi.add(i)), oi), w);
                    let dr = _mm256_sub_pd(nr, vur);
                    let di = _mm256_sub_pd(ni, vui);
                    vdiff = _mm256_fmadd_pd(dr, dr, _mm256_fmadd_pd(di, di, vdiff));
                    let p = _mm256_fmadd_pd(nr, nr, _mm256_mul_pd(ni, ni));
                    vnum = _mm256_fmadd_pd(vnu, p, vnum);
                    vden = _mm256_add_pd(vden, p);
                    _mm256_storeu_pd(ur.add(i), nr);
                    _mm256_storeu_pd(ui.add(i), ni);
                    _mm256_storeu_pd(tr.add(i), _mm256_add_pd(or, nr));
                    _mm256_storeu_pd(ti.add(i), _mm256_add_pd(oi, ni));
                    i += 4;
                }
            }
            let mut lanes = [0.0; 4];
            // SAFETY: lanes holds four f64.
            unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), vnum) };
            num[k] += lanes.iter().sum::<f64>();
            unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), vden) };
            den[k] += lanes.iter().sum::<f64>();
            for i in full..len {
                let g = start + i;
                let (ur, ui) = (u_re[k][g], u_im[k][g]);
                let d = freqs[g] - om;
                let w = 1.0 / (1.0 + alpha * d * d);
                let or = tot_re[i] - ur;
                let oi = tot_im[i] - ui;
                let nr = (t_re[g] - or) * w;
                let ni = (t_im[g] - oi) * w;
                diff_s += (nr - ur) * (nr - ur) + (ni - ui) * (ni - ui);
                let p = nr * nr + ni * ni;
                num[k] += freqs[g] * p;
                den[k] += p;
                u_re[k][g] = nr;
                u_im[k][g] = ni;
                tot_re[i] = or + nr;
                tot_im[i] = oi + ni;
            }
        }
        start = end;
    }
    let mut lanes = [0.0; 4];
    // SAFETY: lanes holds four f64.
    unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), vdiff) };
    diff_s + lanes.iter().sum::<f64>()
}

/// The sweep kernel: per block of bins, the running total Σ_k û_k, then each mode's Wiener
/// update in 4 independent lanes (so the compiler can keep them in SIMD registers).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn sweep_generic(
    u_re: &mut [&mut [f64]],
    u_im: &mut [&mut [f64]],
    t_re: &[f64],
    t_im: &[f64],
    freqs: &[f64],
    omega: &[f64],
    alpha: f64,
    num: &mut [f64],
    den: &mut [f64],
) -> f64 {
    const L: usize = 4;
    let m = t_re.len();
    let mut tot_re = [0.0; BLOCK];
    let mut tot_im = [0.0; BLOCK];
    let mut diff = [0.0; L];
    let mut start = 0;
    while start < m {
        let len = BLOCK.min(m - start);
        let end = start + len;
        tot_re[..len].fill(0.0);
        tot_im[..len].fill(0.0);
        for k in 0..omega.len() {
            for (t, v) in tot_re[..len].iter_mut().zip(&u_re[k][start..end]) {
                *t += v;
            }
            for (t, v) in tot_im[..len].iter_mut().zip(&u_im[k][start..end]) {
                *t += v;
            }
        }
        for (k, &om) in omega.iter().enumerate() {
            let mut acc_num = [0.0; L];
            let mut acc_den = [0.0; L];
            let lanes = u_re[k][start..end]
                .chunks_exact_mut(L)
                .zip(u_im[k][start..end].chunks_exact_mut(L))
                .zip(tot_re[..len].chunks_exact_mut(L))
                .zip(tot_im[..len].chunks_exact_mut(L))
                .zip(t_re[start..end].chunks_exact(L))
                .zip(t_im[start..end].chunks_exact(L))
                .zip(freqs[start..end].chunks_exact(L));
            for ((((((ur, ui), tr), ti), fr), fi), nu) in lanes {
                let ur: &mut [f64; L] = ur.try_into().expect("chunk of L");
                let ui: &mut [f64; L] = ui.try_into().expect("chunk of L");
                let tr: &mut [f64; L] = tr.try_into().expect("chunk of L");
                let ti: &mut [f64; L] = ti.try_into().expect("chunk of L");
                let fr: &[f64; L] = fr.try_into().expect("chunk of L");
                let fi: &[f64; L] = fi.try_into().expect("chunk of L");
                let nu: &[f64; L] = nu.try_into().expect("chunk of L");
                for l in 0..L {
                    let d = nu[l] - om;
                    let w = 1.0 / (1.0 + alpha * d * d);
                    let or = tr[l] - ur[l];
                    let oi = ti[l] - ui[l];
                    let nr = (fr[l] - or) * w;
                    let ni = (fi[l] - oi) * w;
                    let dr = nr - ur[l];
                    let di = ni - ui[l];
                    diff[l] += dr * dr + di * di;
                    let p = nr * nr + ni * ni;
                    acc_num[l] += nu[l] * p;
                    acc_den[l] += p;
                    ur[l] = nr;
                    ui[l] = ni;
                    tr[l] = or + nr;
                    ti[l] = oi + ni;
                }
            }
            for i in start + len / L * L..end {
                let j = i - start;
                let (ur, ui) = (u_re[k][i], u_im[k][i]);
                let d = freqs[i] - om;
                let w = 1.0 / (1.0 + alpha * d * d);
                let or = tot_re[j] - ur;
                let oi = tot_im[j] - ui;
                let nr = (t_re[i] - or) * w;
                let ni = (t_im[i] - oi) * w;
                diff[0] += (nr - ur) * (nr - ur) + (ni - ui) * (ni - ui);
                let p = nr * nr + ni * ni;
                acc_num[0] += freqs[i] * p;
                acc_den[0] += p;
                u_re[k][i] = nr;
                u_im[k][i] = ni;
                tot_re[j] = or + nr;
                tot_im[j] = oi + ni;
            }
            num[k] += acc_num.iter().sum::<f64>();
            den[k] += acc_den.iter().sum::<f64>();
        }
        start = end;
    }
    diff.iter().sum()
}

/// Output of [`vmd`].
#[derive(Clone, Debug, Serialize)]
pub struct VmdResult {
    /// K modes, each as long as the input, lowest centre frequency first (init order).
    pub modes: Vec<Vec<f64>>,
    /// Final centre frequencies in cycles per sample (0 … 0.5).
    pub omega: Vec<f64>,
    pub iterations: usize,
    /// Last value of the convergence measure.
    pub u_diff: f64,
}

/// Decomposes `x` into K band-limited modes by VMD.
///
/// Formula (paper 002 eqs. 5-8; Dragomiretskiy & Zosso 2014, Algorithm 2): on the one-sided
/// spectrum of the mirror-extended signal (length T = 2n), Gauss-Seidel updates
/// û_k ← (f̂ − Σ_{i≠k} û_i − λ̂/2) / (1 + α(ω − ω_k)²) (ω in cycles/sample, as vmdpy),
/// ω_k ← Σ ω|û_k|² / Σ |û_k|², λ̂ ← λ̂ + τ(Σ û_k − f̂), until
/// Σ_k ‖û_k^{n+1} − û_k^n‖²/T < tol or `max_iter`. Returns the last iterate (as the MATLAB
/// reference; vmdpy returns the one before, a 1e-5 mm difference on the paper's signal).
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

    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(t);
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
    // Modes as separate real and imaginary arrays (structure of arrays, vectorisable).
    let f_re: Vec<f64> = f_hat.iter().map(|c| c.re).collect();
    let f_im: Vec<f64> = f_hat.iter().map(|c| c.im).collect();
    let mut t_re = f_re.clone();
    let mut t_im = f_im.clone();
    let mut lam_re = vec![0.0; m];
    let mut lam_im = vec![0.0; m];
    let mut u_re = vec![vec![0.0; m]; k_modes];
    let mut u_im = vec![vec![0.0; m]; k_modes];
    let mut iterations = 0;
    let mut u_diff = f64::INFINITY;
    let threads = if m >= PARALLEL_MIN_BINS {
        std::thread::available_parallelism()
            .map_or(1, |p| p.get())
            .min(2)
    } else {
        1
    };
    while iterations < params.max_iter.saturating_sub(1) && u_diff > params.tol {
        let mut num = vec![0.0; k_modes];
        let mut den = vec![0.0; k_modes];
        let diff = sweep(
            &mut u_re,
            &mut u_im,
            &t_re,
            &t_im,
            &freqs,
            &omega,
            params.alpha,
            &mut num,
            &mut den,
            threads,
        );
        for k in 0..k_modes {
            if !(params.dc && k == 0) && den[k] > 0.0 {
                omega[k] = num[k] / den[k];
            }
        }
        if params.tau != 0.0 {
            for b in 0..m {
                let (sr, si) =
                    (0..k_modes).fold((0.0, 0.0), |(a, c), k| (a + u_re[k][b], c + u_im[k][b]));
                lam_re[b] += params.tau * (sr - f_re[b]);
                lam_im[b] += params.tau * (si - f_im[b]);
                t_re[b] = f_re[b] - 0.5 * lam_re[b];
                t_im[b] = f_im[b] - 0.5 * lam_im[b];
            }
        }
        iterations += 1;
        u_diff = f64::EPSILON + diff / t as f64;
    }
    let u: Vec<Complex<f64>> = (0..m)
        .flat_map(|b| (0..k_modes).map(move |k| (b, k)))
        .map(|(b, k)| Complex::new(u_re[k][b], u_im[k][b]))
        .collect();

    let inv = planner.plan_fft_inverse(t);
    let mut modes = Vec::with_capacity(k_modes);
    let mut buf = inv.make_input_vec();
    let mut out = inv.make_output_vec();
    for k in 0..k_modes {
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
/// cited as [30] in paper 002). Known bad cases: a mode that is ~0 everywhere (returns 0).
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
/// Reference: paper 002 section 3.1 (K = 7 found this way for its 2,025-point signals) and
/// Chang et al. 2021. Known bad cases: costs up to k_max − 1 VMD runs; on clean signals of
/// a few pure tones the highest mode's IF can tie between K and K + 1 and the search stops
/// one or more modes early (the screening then still keeps every tone's mode).
pub fn choose_k(x: &[f64], params: &VmdParams, k_max: usize) -> Result<usize, Error> {
    let mut prev_top = -1.0;
    for k in 2..=k_max.max(2) {
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

#[cfg(test)]
mod tests {
    use super::*;

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
    fn instantaneous_frequency_of_a_tone() {
        let x: Vec<f64> = (0..1000)
            .map(|k| (2.0 * std::f64::consts::PI * 0.05 * k as f64).sin())
            .collect();
        assert!((mean_instantaneous_frequency(&x) - 0.05).abs() < 1e-3);
    }
}
