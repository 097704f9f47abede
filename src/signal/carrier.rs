//! Narrow-band ("carrier") smoothing: a sinusoidal systematic error with a slowly varying
//! envelope, h(t) = a(t)·cos 2πft + b(t)·sin 2πft, fitted by penalised least squares with
//! a(t), b(t) cubic B-splines and the penalty weight chosen by GCV.
//!
//! Why: a VMD mode is a Wiener filter ~1/√α wide and keeps every bit of noise inside that
//! band, and a broadband smoother wide enough to pass the carrier also passes all the noise
//! below it. A carrier with a slow envelope occupies only a few degrees of freedom: this
//! is the varying-coefficient model of Hastie & Tibshirani (1993, JRSS B 55) with P-spline
//! coefficients (Eilers & Marx 1996), the AM-FM view of a mode that VMD itself assumes
//! (Dragomiretskiy & Zosso 2014, §2). Written here: no crate fits it.
//!
//! The envelope basis has one cubic B-spline per 4 carrier periods (at most 120), so the
//! envelope's band (|ν − f| ≲ f/4) stays clear of a trend below f/2 and the two parts
//! can be told apart; the order-2 penalty's null space is a linear envelope, which also
//! absorbs a small error in f.

use super::error::{Error, check_signal};
use super::whittaker::minimise_log_lambda;
use crate::numeric::brent::minimize as brent_minimize;
use crate::numeric::bspline::uniform_cubic;
use crate::numeric::penalty::difference_penalty;
use nalgebra::{DMatrix, DVector};

/// Most envelope basis functions per quadrature (keeps the 2m × 2m eigenproblem small).
pub const MAX_BASIS: usize = 120;
/// Fewest carrier periods in the record for a carrier fit to be attempted.
pub const MIN_PERIODS: f64 = 8.0;

/// A fitted carrier.
#[derive(Clone, Debug)]
pub struct CarrierFit {
    /// h(t) at every sample, units of the input.
    pub signal: Vec<f64>,
    /// Carrier frequency f (cycles/sample).
    pub frequency: f64,
    /// Effective degrees of freedom tr(H) at the GCV weight.
    pub edf: f64,
    /// Envelope basis functions per quadrature.
    pub basis: usize,
}

/// The envelope design of one carrier: precomputed once, refitted to several inputs.
pub struct Carrier {
    n: usize,
    f: f64,
    m: usize,
    /// cos 2πft and sin 2πft at every sample.
    cos: Vec<f64>,
    sin: Vec<f64>,
    /// Cholesky factor R of XᵀX (XᵀX = RᵀR), R⁻¹, and the eigenpairs of R⁻ᵀPR⁻¹.
    r_inv: DMatrix<f64>,
    eig_vectors: DMatrix<f64>,
    eig_values: DVector<f64>,
}

impl Carrier {
    /// Interval index, local coordinate and the carrier's (cos, sin) at sample t.
    fn row(&self, t: usize) -> (usize, [f64; 4], f64, f64) {
        let (j, w) = uniform_cubic(t as f64, [0.0, (self.n - 1) as f64], self.m - 3);
        (j, w, self.cos[t], self.sin[t])
    }

    /// Sets up the carrier at frequency `f` (cycles/sample) for `n` samples: envelope basis
    /// size m = clamp(round(n·f/4), 4, [`MAX_BASIS`]), second-difference penalty on each
    /// quadrature's coefficients, and the Demmler-Reinsch eigenbasis that makes every GCV
    /// evaluation O(m). Cost O(n·64 + m³).
    pub fn new(n: usize, f: f64) -> Result<Self, Error> {
        if !(f.is_finite() && f > 0.0 && f < 0.5) || n < 16 {
            return Err(Error::BadParam {
                name: "frequency",
                reason: format!(
                    "a carrier needs 0 < f < 0.5 cycles/sample and n ≥ 16 (f = {f}, n = {n})"
                ),
            });
        }
        let m = ((n as f64 * f / 4.0).round() as usize).clamp(4, MAX_BASIS);
        let mut c = Carrier {
            n,
            f,
            m,
            cos: Vec::with_capacity(n),
            sin: Vec::with_capacity(n),
            r_inv: DMatrix::zeros(0, 0),
            eig_vectors: DMatrix::zeros(0, 0),
            eig_values: DVector::zeros(0),
        };
        for t in 0..n {
            let (s, co) = (2.0 * std::f64::consts::PI * f * t as f64).sin_cos();
            c.cos.push(co);
            c.sin.push(s);
        }
        let p = 2 * m;
        // XᵀX accumulated in a plain column-major array (as DMatrix stores it; the same
        // additions in the same order), its upper triangle only, then wrapped.
        let mut flat = vec![0.0; p * p];
        for t in 0..n {
            let (j, w, cs, sn) = c.row(t);
            let vals = [
                w[0] * cs,
                w[1] * cs,
                w[2] * cs,
                w[3] * cs,
                w[0] * sn,
                w[1] * sn,
                w[2] * sn,
                w[3] * sn,
            ];
            let idx = [
                j,
                j + 1,
                j + 2,
                j + 3,
                m + j,
                m + j + 1,
                m + j + 2,
                m + j + 3,
            ];
            // idx ascends, so a ≤ b is the upper triangle (row ≤ column).
            for b in 0..8 {
                let col = &mut flat[idx[b] * p..idx[b] * p + p];
                for a in 0..=b {
                    col[idx[a]] += vals[a] * vals[b];
                }
            }
        }
        // The lower triangle: the same products (x·y = y·x exactly) in the same order.
        for col in 0..p {
            for row in col + 1..p {
                flat[col * p + row] = flat[row * p + col];
            }
        }
        let mut xtx = DMatrix::<f64>::from_vec(p, p, flat);
        // Second-difference penalty DᵀD on each block.
        let mut pen = DMatrix::<f64>::zeros(p, p);
        let block_pen = difference_penalty(m, 2);
        for block in [0, m] {
            pen.view_mut((block, block), (m, m)).copy_from(&block_pen);
        }
        // A tiny ridge keeps the factorisation defined when a basis function sees few
        // samples (short records); 1e-10 of the mean diagonal changes no fit visibly.
        let ridge = 1e-10 * xtx.trace() / p as f64;
        for i in 0..p {
            xtx[(i, i)] += ridge;
        }
        let chol = xtx.cholesky().ok_or(Error::BadParam {
            name: "frequency",
            reason: "the carrier's envelope design is singular".into(),
        })?;
        let l = chol.l(); // XᵀX = L Lᵀ, R = Lᵀ
        let l_inv = l.clone().try_inverse().ok_or(Error::BadParam {
            name: "frequency",
            reason: "the carrier's envelope design is singular".into(),
        })?;
        let r_inv = l_inv.transpose();
        let mtx = &l_inv * &pen * &r_inv;
        let mtx = (&mtx + mtx.transpose()) * 0.5;
        let eig = mtx.symmetric_eigen();
        c.r_inv = r_inv;
        c.eig_vectors = eig.eigenvectors;
        c.eig_values = eig.eigenvalues.map(|v| v.max(0.0));
        Ok(c)
    }

    /// Fits the carrier to `r` (n samples) with the penalty weight minimising GCV(λ) =
    /// n·RSS/(n − tr H)² (Craven & Wahba 1979); returns h(t) and tr H.
    ///
    /// Formula: with XᵀX = RᵀR and R⁻ᵀPR⁻¹ = U diag(s) Uᵀ, z = UᵀR⁻ᵀXᵀr, the fit at λ has
    /// g_i = 1/(1 + λ s_i), tr H = Σ g_i and RSS = ‖r‖² − Σ (2g_i − g_i²) z_i².
    pub fn fit(&self, r: &[f64]) -> Result<CarrierFit, Error> {
        check_signal("carrier", r, 16)?;
        if r.len() != self.n {
            return Err(Error::BadParam {
                name: "signal",
                reason: format!(
                    "{} samples given to a carrier set up for {}",
                    r.len(),
                    self.n
                ),
            });
        }
        let (m, n) = (self.m, self.n as f64);
        let mut xtr = DVector::<f64>::zeros(2 * m);
        for (t, &v) in r.iter().enumerate() {
            let (j, w, cs, sn) = self.row(t);
            for i in 0..4 {
                xtr[j + i] += w[i] * cs * v;
                xtr[m + j + i] += w[i] * sn * v;
            }
        }
        let z = self.eig_vectors.transpose() * (self.r_inv.transpose() * &xtr);
        let rr: f64 = r.iter().map(|v| v * v).sum();
        let s = &self.eig_values;
        let parts = |lam: f64| {
            let (mut fit2, mut tr) = (0.0, 0.0);
            for i in 0..s.len() {
                let g = 1.0 / (1.0 + lam * s[i]);
                fit2 += (2.0 * g - g * g) * z[i] * z[i];
                tr += g;
            }
            ((rr - fit2).max(0.0), tr)
        };
        // λ relative to the scale of the eigenvalues: from 1e-6 to 1e10 of 1/mean(s).
        let scale = s.len() as f64 / s.iter().sum::<f64>().max(f64::MIN_POSITIVE);
        let p = minimise_log_lambda(-6.0, 10.0, |p| {
            let (rss, tr) = parts(scale * 10f64.powf(p));
            if tr >= n - 1.0 {
                f64::INFINITY
            } else {
                n * rss / ((n - tr) * (n - tr))
            }
        });
        let lam = scale * 10f64.powf(p);
        let (_, edf) = parts(lam);
        let g = DVector::from_iterator(s.len(), s.iter().map(|si| 1.0 / (1.0 + lam * si)));
        let coef = &self.r_inv * (&self.eig_vectors * z.component_mul(&g));
        let signal = (0..self.n)
            .map(|t| {
                let (j, w, cs, sn) = self.row(t);
                (0..4)
                    .map(|i| w[i] * (coef[j + i] * cs + coef[m + j + i] * sn))
                    .sum()
            })
            .collect();
        Ok(CarrierFit {
            signal,
            frequency: self.f,
            edf,
            basis: m,
        })
    }
}

/// Hann-windowed periodogram power of `r` at frequency `f` (cycles/sample), scaled so that
/// white noise of variance σ² has expectation σ² and a sinusoid of amplitude A (≫ noise)
/// gives ≈ A²·n/6.
pub fn hann_power(r: &[f64], f: f64) -> f64 {
    let n = r.len();
    let (mut re, mut im, mut w2) = (0.0, 0.0, 0.0);
    let tau = 2.0 * std::f64::consts::PI;
    // Phasor recurrences for e^{-i2πft} and the window's cos(2πt/n), re-anchored every 1024
    // samples so that rounding cannot build up.
    let (step_c, step_w) = ((-tau * f).sin_cos(), (tau / n as f64).sin_cos());
    let (mut pc, mut pw) = ((0.0, 1.0), (0.0, 1.0));
    for (t, &v) in r.iter().enumerate() {
        if t % 1024 == 0 {
            pc = (-tau * f * t as f64).sin_cos();
            pw = (tau * t as f64 / n as f64).sin_cos();
        }
        let w = 0.5 - 0.5 * pw.1;
        re += w * v * pc.1;
        im += w * v * pc.0;
        w2 += w * w;
        pc = (
            pc.0 * step_c.1 + pc.1 * step_c.0,
            pc.1 * step_c.1 - pc.0 * step_c.0,
        );
        pw = (
            pw.0 * step_w.1 + pw.1 * step_w.0,
            pw.1 * step_w.1 - pw.0 * step_w.0,
        );
    }
    (re * re + im * im) / w2.max(f64::MIN_POSITIVE)
}

/// The strongest spectral line of `r` at frequencies ≥ [`MIN_PERIODS`]/n: the largest
/// interior local maximum of its Hann periodogram (4× zero-padded FFT), refined by Brent's
/// method on [`hann_power`]. Returns (f, power) or None when the record is too
/// short. An interior maximum is required so that the skirt of a trend is not taken for a line.
pub fn strongest_line(r: &[f64]) -> Option<(f64, f64)> {
    let n = r.len();
    if n < 32 {
        return None;
    }
    let len = 4 * n;
    let fft = super::fft::forward(len);
    // The window, per length once for the process (one cosine per sample: at 2,025 samples
    // as much as the transform itself, for every strong mode of every decomposition).
    let hann = super::fft::table(super::fft::Table::Hann, n, || {
        (0..n)
            .map(|t| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * t as f64 / n as f64).cos())
            .collect()
    });
    let mut buf = vec![0.0; len];
    for ((b, &v), &w) in buf.iter_mut().zip(r).zip(hann.iter()) {
        *b = v * w;
    }
    let mut spec = fft.make_output_vec();
    fft.process(&mut buf, &mut spec).ok()?;
    let power: Vec<f64> = spec.iter().map(|c| c.norm_sqr()).collect();
    let first = ((MIN_PERIODS / n as f64) * len as f64).ceil() as usize;
    let mut best: Option<(usize, f64)> = None;
    for b in first.max(1)..power.len().saturating_sub(1) {
        if power[b] > power[b - 1]
            && power[b] >= power[b + 1]
            && best.is_none_or(|(_, p)| power[b] > p)
        {
            best = Some((b, power[b]));
        }
    }
    let (b, _) = best?;
    // Refine within ±1 padded bin: maximise the power by Brent's method (the project's one
    // 1-D minimiser), to 1/(1000 n) in frequency.
    let (lo, hi) = ((b as f64 - 1.0) / len as f64, (b as f64 + 1.0) / len as f64);
    let (f, neg_power) = brent_minimize(|f| -hann_power(r, f), lo, hi, 1e-3 / n as f64, 60);
    Some((f, -neg_power))
}

#[cfg(test)]
mod tests;
