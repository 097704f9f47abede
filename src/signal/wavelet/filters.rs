//! Orthogonal wavelet filter banks: Daubechies (db1..db10, minimum phase) and symlets
//! (sym2..sym10, least-asymmetric root choice), in PyWavelets' orientation.
//!
//! Written here (no crate): the Rust wavelet crates are partial or unmaintained (DESIGN.md).
//! The filters are computed from Daubechies' spectral factorisation instead of being typed in,
//! so both families come from one formula; the conformance tests compare them with
//! PyWavelets to 1e-10.

use crate::signal::error::Error;
use nalgebra::{Complex, DMatrix};

/// The four filters of an orthogonal wavelet, in PyWavelets' orientation.
#[derive(Clone, Debug, PartialEq)]
pub struct Wavelet {
    /// PyWavelets name (`db4`, `sym8`, `haar`, ...).
    pub name: String,
    /// Decomposition low-pass (scaling) filter.
    pub dec_lo: Vec<f64>,
    /// Decomposition high-pass (wavelet) filter.
    pub dec_hi: Vec<f64>,
    /// Reconstruction low-pass filter (`dec_lo` reversed).
    pub rec_lo: Vec<f64>,
    /// Reconstruction high-pass filter (`dec_hi` reversed).
    pub rec_hi: Vec<f64>,
}

type C64 = Complex<f64>;

/// Roots of the real polynomial `c[0] + c[1] y + ... + c[m] y^m` (eigenvalues of the
/// companion matrix, then Newton-polished in complex arithmetic).
fn poly_roots(c: &[f64]) -> Vec<C64> {
    let m = c.len() - 1;
    if m == 0 {
        return Vec::new();
    }
    let mut comp = DMatrix::<f64>::zeros(m, m);
    for i in 1..m {
        comp[(i, i - 1)] = 1.0;
    }
    for i in 0..m {
        comp[(i, m - 1)] = -c[i] / c[m];
    }
    let mut roots: Vec<C64> = comp.complex_eigenvalues().iter().copied().collect();
    for r in roots.iter_mut() {
        for _ in 0..8 {
            let (mut p, mut dp) = (C64::new(0.0, 0.0), C64::new(0.0, 0.0));
            for &ck in c.iter().rev() {
                dp = dp * *r + p;
                p = p * *r + C64::new(ck, 0.0);
            }
            if dp.norm() == 0.0 {
                break;
            }
            *r -= p / dp;
        }
    }
    roots
}

fn binomial(n: u64, k: u64) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// Multiplies polynomials in z^-1 with complex coefficients.
fn poly_mul(a: &[C64], b: &[C64]) -> Vec<C64> {
    let mut out = vec![C64::new(0.0, 0.0); a.len() + b.len() - 1];
    for (i, &x) in a.iter().enumerate() {
        for (j, &y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// Zeros of Daubechies' Q(z) for order `p`: one `z` of each reciprocal pair `(z, 1/z)`,
/// grouped so that complex-conjugate pairs stay together (index of group per zero).
fn daubechies_zero_groups(p: usize) -> Vec<Vec<C64>> {
    // P(y) = sum_k C(p-1+k, k) y^k with y = sin^2(w/2) = (2 - z - 1/z)/4.
    let coeffs: Vec<f64> = (0..p)
        .map(|k| binomial((p - 1 + k) as u64, k as u64))
        .collect();
    let ys = poly_roots(&coeffs);
    let mut groups: Vec<Vec<C64>> = Vec::new();
    let mut used = vec![false; ys.len()];
    for i in 0..ys.len() {
        if used[i] {
            continue;
        }
        used[i] = true;
        let inner = |y: C64| {
            let b = C64::new(1.0, 0.0) - y * 2.0;
            let d = (b * b - C64::new(1.0, 0.0)).sqrt();
            let (z1, z2) = (b + d, b - d);
            if z1.norm() < z2.norm() { z1 } else { z2 }
        };
        let mut g = vec![inner(ys[i])];
        if ys[i].im.abs() > 1e-9 {
            if let Some(j) =
                (i + 1..ys.len()).find(|&j| !used[j] && (ys[j] - ys[i].conj()).norm() < 1e-6)
            {
                used[j] = true;
                g.push(inner(ys[j]));
            }
        }
        groups.push(g);
    }
    groups
}

/// Builds the low-pass reconstruction filter from chosen zeros: sqrt(2)-normalised
/// `(1+z^-1)^p * prod (1 - z_i z^-1)`.
fn filter_from_zeros(p: usize, zeros: &[C64]) -> Vec<f64> {
    let mut h = vec![C64::new(1.0, 0.0)];
    for _ in 0..p {
        h = poly_mul(&h, &[C64::new(1.0, 0.0), C64::new(1.0, 0.0)]);
    }
    for &z in zeros {
        h = poly_mul(&h, &[C64::new(1.0, 0.0), -z]);
    }
    let re: Vec<f64> = h.iter().map(|c| c.re).collect();
    let s: f64 = re.iter().sum();
    re.iter()
        .map(|v| v * std::f64::consts::SQRT_2 / s)
        .collect()
}

/// Deviation of a filter's phase from linear (least-squares residual of the unwrapped phase
/// over (0, pi)); the symlet choice minimises it.
fn phase_nonlinearity(h: &[f64]) -> f64 {
    let m = 256;
    let mut prev = 0.0;
    let mut offset = 0.0;
    let mut phases = Vec::with_capacity(m);
    let mut ws = Vec::with_capacity(m);
    for i in 1..m {
        let w = std::f64::consts::PI * i as f64 / m as f64 * 0.95;
        let v: C64 = h
            .iter()
            .enumerate()
            .map(|(k, &c)| C64::from_polar(c, -w * k as f64))
            .sum();
        let mut ph = v.arg() + offset;
        while ph - prev > std::f64::consts::PI {
            ph -= 2.0 * std::f64::consts::PI;
            offset -= 2.0 * std::f64::consts::PI;
        }
        while ph - prev < -std::f64::consts::PI {
            ph += 2.0 * std::f64::consts::PI;
            offset += 2.0 * std::f64::consts::PI;
        }
        prev = ph;
        phases.push(ph);
        ws.push(w);
    }
    let n = ws.len() as f64;
    let (mw, mp) = (ws.iter().sum::<f64>() / n, phases.iter().sum::<f64>() / n);
    let sxy: f64 = ws
        .iter()
        .zip(&phases)
        .map(|(w, p)| (w - mw) * (p - mp))
        .sum();
    let sxx: f64 = ws.iter().map(|w| (w - mw).powi(2)).sum();
    let b = sxy / sxx;
    ws.iter()
        .zip(&phases)
        .map(|(w, p)| (p - mp - b * (w - mw)).powi(2))
        .sum()
}

impl Wavelet {
    /// Builds a wavelet by name: `haar`/`db1` … `db10` (Daubechies, minimum phase) or
    /// `sym2` … `sym10` (symlets, least-asymmetric root choice).
    ///
    /// Formula: Daubechies' spectral factorisation, |H(w)|^2 = 2 cos^(2p)(w/2) P(sin^2(w/2)),
    /// P(y) = sum_{k<p} C(p-1+k, k) y^k (Daubechies 1992, Ten Lectures, ch. 6). Filter
    /// orientation and signs follow PyWavelets (`rec_lo` is the factor, `dec_lo` its reverse,
    /// `dec_hi[k] = (-1)^(k+1) rec_lo[k]`, `rec_hi` the reverse of `dec_hi`).
    /// Known bad cases: none in db1..db10/sym2..sym10 (root finding is polished by Newton).
    pub fn new(name: &str) -> Result<Self, Error> {
        let lower = name.to_ascii_lowercase();
        let (family, p) = if lower == "haar" {
            ("db", 1)
        } else if let Some(n) = lower.strip_prefix("db") {
            (
                "db",
                n.parse::<usize>()
                    .map_err(|_| Error::UnknownWavelet(name.into()))?,
            )
        } else if let Some(n) = lower.strip_prefix("sym") {
            (
                "sym",
                n.parse::<usize>()
                    .map_err(|_| Error::UnknownWavelet(name.into()))?,
            )
        } else {
            return Err(Error::UnknownWavelet(name.into()));
        };
        if !(1..=10).contains(&p) || (family == "sym" && p < 2) {
            return Err(Error::UnknownWavelet(name.into()));
        }
        let groups = daubechies_zero_groups(p);
        let rec_lo = if family == "db" || p <= 3 {
            let zeros: Vec<C64> = groups.iter().flatten().copied().collect();
            filter_from_zeros(p, &zeros)
        } else {
            let mut best: Option<(f64, Vec<f64>)> = None;
            for mask in 0..(1u32 << groups.len()) {
                let zeros: Vec<C64> = groups
                    .iter()
                    .enumerate()
                    .flat_map(|(i, g)| {
                        g.iter()
                            .map(move |&z| if mask >> i & 1 == 1 { z.inv() } else { z })
                    })
                    .collect();
                let h = filter_from_zeros(p, &zeros);
                let score = phase_nonlinearity(&h);
                // Reversed filters tie; PyWavelets' orientation has the largest tap in the
                // second half of rec_lo, so keep only that orientation.
                let imax = (0..h.len())
                    .max_by(|&a, &b| h[a].abs().total_cmp(&h[b].abs()))
                    .unwrap_or(0);
                if imax < h.len() / 2 {
                    continue;
                }
                if best.as_ref().is_none_or(|(s, _)| score < *s - 1e-12) {
                    best = Some((score, h));
                }
            }
            best.map(|b| b.1).unwrap_or_default()
        };
        let f = rec_lo.len();
        let dec_lo: Vec<f64> = rec_lo.iter().rev().copied().collect();
        let dec_hi: Vec<f64> = (0..f)
            .map(|k| if k % 2 == 0 { -rec_lo[k] } else { rec_lo[k] })
            .collect();
        let rec_hi: Vec<f64> = dec_hi.iter().rev().copied().collect();
        Ok(Self {
            name: lower,
            dec_lo,
            dec_hi,
            rec_lo,
            rec_hi,
        })
    }

    /// Filter length (2p for dbp/symp).
    pub fn len(&self) -> usize {
        self.dec_lo.len()
    }

    /// Always false (a wavelet has at least two taps); present for clippy's `len` rule.
    pub fn is_empty(&self) -> bool {
        self.dec_lo.is_empty()
    }
}
