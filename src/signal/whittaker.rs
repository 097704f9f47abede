//! Penalised least-squares (Whittaker) smoothing with the smoothing parameter chosen by
//! generalised cross-validation: the "well-tuned smoother" of the coarse-to-fine pipeline's
//! refinement stage. Written here: no crate offers a banded solve plus GCV in O(n log n).

use super::error::{Error, check_signal};
use crate::numeric::brent::minimize_on_grid;
use crate::numeric::penalty::{difference_stencil, reflective_eigenvalues};
use rustfft::num_complex::Complex;
use serde::Serialize;

/// Result of a smoothing run.
#[derive(Clone, Debug, Serialize)]
pub struct Smoothed {
    /// The smoothed signal, same length and unit as the input.
    #[serde(skip)]
    pub signal: Vec<f64>,
    /// Smoothing parameter λ used (dimensionless, per sample spacing).
    pub lambda: f64,
    /// Effective degrees of freedom tr(H) at λ.
    pub edf: f64,
    /// Frequency (cycles/sample) where the smoother's gain is 1/2.
    pub cutoff: f64,
}

/// Largest λ·4^d admitted: keeps the banded solve of I + λDᵀD within ~1e13 condition number.
const MAX_CONDITION: f64 = 1e13;

/// Squared orthonormal DCT-II coefficients of `x` (O(n log n) via a 2n real FFT).
pub(crate) fn dct_power(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let fft = super::fft::forward(2 * n);
    let mut buf: Vec<f64> = x.iter().chain(x.iter().rev()).copied().collect();
    let mut spec = fft.make_output_vec();
    fft.process(&mut buf, &mut spec)
        .expect("buffer sizes from the plan");
    (0..n)
        .map(|k| {
            let tw = Complex::from_polar(1.0, -std::f64::consts::PI * k as f64 / (2 * n) as f64);
            let c = (spec[k] * tw).re / 2.0;
            let scale = if k == 0 {
                1.0 / n as f64
            } else {
                2.0 / n as f64
            };
            c * c * scale
        })
        .collect()
}

/// Minimises a GCV score over log10 λ ∈ [lo, hi]: a scan in steps of at most 0.25, then
/// Brent's method between the best scan point's neighbours, to about 1e-7 in log10 λ
/// ([`minimize_on_grid`]; GCV is smooth in log λ, so the parabolic steps converge in a
/// dozen evaluations where a plain golden section needed 32).
pub(crate) fn minimise_log_lambda(lo: f64, hi: f64, score: impl Fn(f64) -> f64) -> f64 {
    let steps = ((hi - lo) / 0.25).ceil() as usize;
    let grid: Vec<f64> = (0..=steps)
        .map(|i| lo + (hi - lo) * i as f64 / steps as f64)
        .collect();
    minimize_on_grid(score, &grid, 60, 1e-7).0
}

/// Frequency (cycles/sample) at which 1/(1 + λ(2 sin πν)^(2d)) = 1/2.
pub fn half_power_frequency(lambda: f64, d: usize) -> f64 {
    let s = lambda.powf(-1.0 / (2.0 * d as f64)) / 2.0;
    if s >= 1.0 {
        0.5
    } else {
        s.asin() / std::f64::consts::PI
    }
}

/// GCV choice of λ for the d-th-difference Whittaker smoother of `x`.
///
/// Formula: GCV(λ) = (RSS/n) / (1 − tr H/n)² (Craven & Wahba 1979) with RSS and tr H
/// evaluated in the DCT basis that diagonalises the penalty under reflective ends
/// (Garcia 2010, Comput. Stat. Data Anal. 54): G_k = 1/(1 + λ e_k),
/// RSS = Σ (1 − G_k)² c_k², tr H = Σ G_k. O(n) per λ after one O(n log n) DCT.
/// Known bad cases: strongly correlated noise (GCV under-smooths).
pub fn gcv_lambda(x: &[f64], d: usize) -> f64 {
    let n = x.len();
    let c2 = dct_power(x);
    let e = reflective_eigenvalues(n, d);
    let hi = (MAX_CONDITION / 4f64.powi(d as i32)).log10();
    let p = minimise_log_lambda(-4.0, hi, |p| {
        let lam = 10f64.powf(p);
        // Four independent partial sums (vectorisable).
        let (mut rss4, mut tr4) = ([0.0; 4], [0.0; 4]);
        let full = n / 4 * 4;
        for (cs, es) in c2[..full].chunks_exact(4).zip(e[..full].chunks_exact(4)) {
            for l in 0..4 {
                let g = 1.0 / (1.0 + lam * es[l]);
                rss4[l] += (1.0 - g) * (1.0 - g) * cs[l];
                tr4[l] += g;
            }
        }
        for k in full..n {
            let g = 1.0 / (1.0 + lam * e[k]);
            rss4[0] += (1.0 - g) * (1.0 - g) * c2[k];
            tr4[0] += g;
        }
        let (rss, tr): (f64, f64) = (rss4.iter().sum(), tr4.iter().sum());
        let denom = 1.0 - tr / n as f64;
        if denom <= 1e-12 {
            f64::INFINITY
        } else {
            rss / n as f64 / (denom * denom)
        }
    });
    10f64.powf(p)
}

/// Whittaker smoother: z minimising ‖x − z‖² + λ‖D_d z‖² (D_d the d-th difference matrix),
/// i.e. the solution of (I + λ D_dᵀ D_d) z = x by a banded LDLᵀ factorisation in O(n d²).
/// `lambda = None` chooses λ by GCV ([`gcv_lambda`]).
///
/// Reference: Whittaker 1923; Eilers 2003, Anal. Chem. 75 ("A perfect smoother"). The ends
/// are natural (no boundary condition is imposed), so a polynomial of degree < d passes
/// unchanged and sloped ends are not flattened as with mirror extension.
/// Units: those of x. Known bad cases: n ≤ d (returned unchanged); λ is capped so that
/// λ·4^d ≤ 1e13 (very oversampled signals get slightly less smoothing than GCV wants).
pub fn whittaker(x: &[f64], d: usize, lambda: Option<f64>) -> Result<Smoothed, Error> {
    check_signal("whittaker", x, 1)?;
    if !(1..=6).contains(&d) {
        return Err(Error::BadParam {
            name: "smoothing_order",
            reason: "must be between 1 and 6 (difference order of the penalty)".into(),
        });
    }
    let n = x.len();
    if n <= d + 1 {
        return Ok(Smoothed {
            signal: x.to_vec(),
            lambda: 0.0,
            edf: n as f64,
            cutoff: 0.5,
        });
    }
    let lam = match lambda {
        Some(l) if l.is_finite() && l >= 0.0 => l.min(MAX_CONDITION / 4f64.powi(d as i32)),
        Some(_) => {
            return Err(Error::BadParam {
                name: "lambda",
                reason: "must be a finite number >= 0".into(),
            });
        }
        None => gcv_lambda(x, d),
    };
    let signal = solve_banded(x, d, lam);
    let e = reflective_eigenvalues(n, d);
    let edf = e.iter().map(|ek| 1.0 / (1.0 + lam * ek)).sum();
    Ok(Smoothed {
        signal,
        lambda: lam,
        edf,
        cutoff: half_power_frequency(lam, d),
    })
}

/// Solves (I + λ DᵀD) z = x with D the d-th forward difference matrix ((n−d) × n).
fn solve_banded(x: &[f64], d: usize, lam: f64) -> Vec<f64> {
    let n = x.len();
    // Difference stencil c_j = (-1)^(d-j) C(d, j).
    let c = difference_stencil(d);
    // Lower band: a[i*(d+1) + s] = A[i][i-s].
    let w = d + 1;
    let mut a = vec![0.0; n * w];
    for r in 0..n - d {
        for p in 0..=d {
            for q in 0..=p {
                a[(r + p) * w + (p - q)] += lam * c[p] * c[q];
            }
        }
    }
    for i in 0..n {
        a[i * w] += 1.0;
    }
    // Banded LDLᵀ in place: a[i*w + s] becomes L[i][i-s] (s > 0) and D[i] (s = 0).
    for i in 0..n {
        let j0 = i.saturating_sub(d);
        for j in j0..i {
            let mut v = a[i * w + (i - j)];
            for k in j0.max(j.saturating_sub(d))..j {
                v -= a[i * w + (i - k)] * a[j * w + (j - k)] * a[k * w];
            }
            a[i * w + (i - j)] = v / a[j * w];
        }
        let mut dv = a[i * w];
        for k in j0..i {
            let l = a[i * w + (i - k)];
            dv -= l * l * a[k * w];
        }
        a[i * w] = dv;
    }
    let substitute = |rhs: &[f64]| -> Vec<f64> {
        let mut z = rhs.to_vec();
        for i in 0..n {
            for k in i.saturating_sub(d)..i {
                z[i] -= a[i * w + (i - k)] * z[k];
            }
        }
        for i in 0..n {
            z[i] /= a[i * w];
        }
        for i in (0..n).rev() {
            for k in i + 1..(i + w).min(n) {
                z[i] -= a[k * w + (k - i)] * z[k];
            }
        }
        z
    };
    let mut z = substitute(x);
    // Two steps of iterative refinement: the system's condition number reaches ~λ·4^d, and
    // each step divides the error by about that times machine epsilon.
    for _ in 0..2 {
        let mut dz = vec![0.0; n - d];
        for (r, v) in dz.iter_mut().enumerate() {
            *v = (0..=d).map(|j| c[j] * z[r + j]).sum();
        }
        let mut resid: Vec<f64> = x.iter().zip(&z).map(|(a, b)| a - b).collect();
        for (r, v) in dz.iter().enumerate() {
            for j in 0..=d {
                resid[r + j] -= lam * c[j] * v;
            }
        }
        let delta = substitute(&resid);
        for (zi, di) in z.iter_mut().zip(&delta) {
            *zi += di;
        }
    }
    z
}

#[cfg(test)]
mod tests;
