//! Discrete wavelet transform with half-sample symmetric extension (PyWavelets
//! `mode='symmetric'`): one level forward and inverse, the multilevel `wavedec`/`waverec`,
//! and PyWavelets' maximum level.
//!
//! Written here (no crate): the Rust wavelet crates are partial or unmaintained (DESIGN.md);
//! the coefficient lengths and values agree with PyWavelets (tests/signal_reference.rs).

use super::filters::Wavelet;

/// Half-sample symmetric index into a signal of length `n` (PyWavelets `symmetric`).
fn sym_index(i: isize, n: usize) -> usize {
    let period = 2 * n as isize;
    let mut k = i.rem_euclid(period);
    if k >= n as isize {
        k = period - 1 - k;
    }
    k as usize
}

/// One level of the DWT: returns (cA, cD), each of length floor((n + F - 1)/2).
///
/// Formula: `cA[o] = sum_j dec_lo[j] x~[2o + 1 - j]` (x~ the symmetric extension); same with
/// dec_hi for cD. Reference: PyWavelets `pywt.dwt(x, w, mode='symmetric')`.
pub fn dwt(x: &[f64], w: &Wavelet) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let f = w.len();
    let out = (n + f - 1) / 2;
    let mut ca = vec![0.0; out];
    let mut cd = vec![0.0; out];
    for o in 0..out {
        let i = 2 * o + 1;
        let (mut a, mut d) = (0.0, 0.0);
        if i >= f - 1 && i < n {
            for j in 0..f {
                let v = x[i - j];
                a += w.dec_lo[j] * v;
                d += w.dec_hi[j] * v;
            }
        } else {
            for j in 0..f {
                let v = x[sym_index(i as isize - j as isize, n)];
                a += w.dec_lo[j] * v;
                d += w.dec_hi[j] * v;
            }
        }
        ca[o] = a;
        cd[o] = d;
    }
    (ca, cd)
}

/// One level of the inverse DWT ("valid" upsampling convolution); output length 2L - F + 2.
///
/// Formula: `y[m] = sum_k cA[k] rec_lo[m + F - 2 - 2k] + cD[k] rec_hi[m + F - 2 - 2k]`.
/// Reference: PyWavelets `pywt.idwt(cA, cD, w, mode='symmetric')`.
pub fn idwt(ca: &[f64], cd: &[f64], w: &Wavelet) -> Vec<f64> {
    let f = w.len();
    let l = ca.len();
    let out_len = (2 * l + 2).saturating_sub(f);
    let mut y = vec![0.0; out_len];
    for (m, ym) in y.iter_mut().enumerate() {
        let base = m + f - 2;
        // k ranges where 0 <= base - 2k < f
        let k_lo = (base + 1).saturating_sub(f).div_ceil(2);
        let k_hi = (base / 2).min(l - 1);
        let mut s = 0.0;
        for k in k_lo..=k_hi {
            let t = base - 2 * k;
            s += ca[k] * w.rec_lo[t] + cd[k] * w.rec_hi[t];
        }
        *ym = s;
    }
    y
}

/// PyWavelets' default (maximum useful) level: floor(log2(n / (F - 1))), 0 if n < F - 1.
pub fn max_level(n: usize, filter_len: usize) -> usize {
    if filter_len <= 1 || n < filter_len - 1 {
        return 0;
    }
    ((n as f64) / (filter_len as f64 - 1.0)).log2().floor() as usize
}

/// Multilevel DWT: `[cA_L, cD_L, …, cD_1]` exactly as `pywt.wavedec(x, w, 'symmetric', level)`.
pub fn wavedec(x: &[f64], w: &Wavelet, level: usize) -> Vec<Vec<f64>> {
    let mut details = Vec::with_capacity(level);
    let mut a = x.to_vec();
    for _ in 0..level {
        crate::numeric::stop::check();
        let (ca, cd) = dwt(&a, w);
        details.push(cd);
        a = ca;
    }
    let mut out = vec![a];
    out.extend(details.into_iter().rev());
    out
}

/// Multilevel inverse: `pywt.waverec` (drops the last approximation sample when it is one
/// longer than the details). The result may be one sample longer than the original odd-length
/// signal; callers trim.
pub fn waverec(coeffs: &[Vec<f64>], w: &Wavelet) -> Vec<f64> {
    let mut a = coeffs[0].clone();
    for d in &coeffs[1..] {
        crate::numeric::stop::check();
        if a.len() == d.len() + 1 {
            a.pop();
        }
        a = idwt(&a, d, w);
    }
    a
}
