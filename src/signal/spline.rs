//! Cubic interpolating splines with not-a-knot end conditions (as scipy's `CubicSpline`,
//! which PyEMD uses for its envelopes). Written here (the tridiagonal solve is
//! `numeric::tridiag`): the spline crates either allocate per evaluation or lack not-a-knot ends.

use super::error::Error;
use crate::numeric::tridiag;

/// A C² piecewise cubic through (x_i, y_i), stored as values and slopes at the knots
/// (Hermite form).
#[derive(Clone, Debug)]
pub struct CubicSpline {
    x: Vec<f64>,
    y: Vec<f64>,
    slopes: Vec<f64>,
}

impl CubicSpline {
    /// Interpolating cubic spline with not-a-knot ends (third derivative continuous at the
    /// second and second-to-last knots); a parabola through 3 points; a line through 2.
    ///
    /// Formula: slopes s_i from the tridiagonal system
    /// Δx_i s_{i-1} + 2(Δx_{i-1} + Δx_i) s_i + Δx_{i-1} s_{i+1} = 3(Δx_i m_{i-1} + Δx_{i-1} m_i)
    /// (m_i the secant slopes) with the not-a-knot rows of de Boor, A Practical Guide to
    /// Splines, ch. IV. Units: those of x and y. Errors: fewer than 2 knots, knots not
    /// strictly increasing, non-finite values.
    pub fn not_a_knot(x: &[f64], y: &[f64]) -> Result<Self, Error> {
        let n = x.len();
        if n < 2 || y.len() != n {
            return Err(Error::TooShort {
                method: "cubic spline",
                got: n.min(y.len()),
                min: 2,
            });
        }
        if x.windows(2)
            .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
            || x.iter().chain(y).any(|v| !v.is_finite())
        {
            return Err(Error::BadParam {
                name: "knots",
                reason: "spline knots must be finite and strictly increasing".into(),
            });
        }
        let dx: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
        let m: Vec<f64> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / dx[i]).collect();
        let slopes = if n == 2 {
            vec![m[0], m[0]]
        } else if n == 3 {
            // The parabola through three points.
            let c = (m[1] - m[0]) / (x[2] - x[0]);
            let s0 = m[0] - c * dx[0];
            let s1 = m[0] + c * dx[0];
            let s2 = m[1] + c * dx[1];
            vec![s0, s1, s2]
        } else {
            let mut lower = vec![0.0; n];
            let mut diag = vec![0.0; n];
            let mut upper = vec![0.0; n];
            let mut rhs = vec![0.0; n];
            let d0 = x[2] - x[0];
            diag[0] = dx[1];
            upper[0] = d0;
            rhs[0] = ((dx[0] + 2.0 * d0) * dx[1] * m[0] + dx[0] * dx[0] * m[1]) / d0;
            for i in 1..n - 1 {
                lower[i] = dx[i];
                diag[i] = 2.0 * (dx[i - 1] + dx[i]);
                upper[i] = dx[i - 1];
                rhs[i] = 3.0 * (dx[i] * m[i - 1] + dx[i - 1] * m[i]);
            }
            let dn = x[n - 1] - x[n - 3];
            lower[n - 1] = dn;
            diag[n - 1] = dx[n - 3];
            rhs[n - 1] = (dx[n - 2] * dx[n - 2] * m[n - 3]
                + (2.0 * dn + dx[n - 2]) * dx[n - 3] * m[n - 2])
                / dn;
            tridiag::solve(&lower, &diag, &upper, &mut rhs);
            rhs
        };
        Ok(Self {
            x: x.to_vec(),
            y: y.to_vec(),
            slopes,
        })
    }

    fn segment(&self, t: f64) -> usize {
        let n = self.x.len();
        match self.x.partition_point(|&v| v <= t) {
            0 => 0,
            i if i >= n => n - 2,
            i => i - 1,
        }
    }

    /// Value at `t` (extrapolates with the end cubic outside the knots).
    pub fn eval(&self, t: f64) -> f64 {
        self.eval_with_derivative(t).0
    }

    /// Value and first derivative at `t`.
    pub fn eval_with_derivative(&self, t: f64) -> (f64, f64) {
        let i = self.segment(t);
        let h = self.x[i + 1] - self.x[i];
        let s = (t - self.x[i]) / h;
        let (y0, y1) = (self.y[i], self.y[i + 1]);
        let (d0, d1) = (self.slopes[i] * h, self.slopes[i + 1] * h);
        let s2 = s * s;
        let s3 = s2 * s;
        let v = (2.0 * s3 - 3.0 * s2 + 1.0) * y0
            + (s3 - 2.0 * s2 + s) * d0
            + (-2.0 * s3 + 3.0 * s2) * y1
            + (s3 - s2) * d1;
        let dv = ((6.0 * s2 - 6.0 * s) * y0
            + (3.0 * s2 - 4.0 * s + 1.0) * d0
            + (-6.0 * s2 + 6.0 * s) * y1
            + (3.0 * s2 - 2.0 * s) * d1)
            / h;
        (v, dv)
    }

    /// Values at the integer sample positions 0..n (one pass, no search per sample): per
    /// segment the cubic in power form of s = (t − x_i)/h, evaluated by Horner.
    pub fn eval_samples(&self, n: usize) -> Vec<f64> {
        let mut out = vec![0.0; n];
        self.eval_samples_into(&mut out);
        out
    }

    /// [`CubicSpline::eval_samples`] written into `out` (n = `out.len()` samples, n < 2³¹), so
    /// that a caller evaluating many splines (EMD's envelopes, two per sift) reuses one
    /// buffer. The same arithmetic, so the same bits.
    pub fn eval_samples_into(&self, out: &mut [f64]) {
        let n = out.len();
        let nk = self.x.len();
        let mut k = 0usize;
        for i in 0..nk - 1 {
            // Segment i serves t < x[i+1] (the first also everything left of x[0], the
            // last everything from x[n-2] on).
            let stop = if i + 2 == nk {
                n
            } else {
                // First integer t with t >= x[i+1].
                let e = self.x[i + 1].ceil();
                if e <= 0.0 { 0 } else { (e as usize).min(n) }
            };
            if stop <= k {
                continue;
            }
            let h = self.x[i + 1] - self.x[i];
            let inv_h = 1.0 / h;
            let (y0, y1) = (self.y[i], self.y[i + 1]);
            let (d0, d1) = (self.slopes[i] * h, self.slopes[i + 1] * h);
            let c2 = -3.0 * y0 - 2.0 * d0 + 3.0 * y1 - d1;
            let c3 = 2.0 * y0 + d0 - 2.0 * y1 + d1;
            let cubic = [self.x[i], inv_h, y0, d0, c2, c3];
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports the feature the function is compiled for.
                unsafe { horner_avx2(&mut out[k..stop], k, cubic) };
                k = stop;
                continue;
            }
            horner(&mut out[k..stop], k, cubic);
            k = stop;
        }
    }
}

/// `out[i] = y0 + s·(d0 + s·(c2 + s·c3))` with s = (first + i − x0)·inv_h: one segment of
/// [`CubicSpline::eval_samples_into`], `cubic` = [x0, inv_h, y0, d0, c2, c3]. The sample
/// index as i32 → f64 is exact (n < 2³¹) and converts in vector registers.
#[inline(always)]
fn horner(out: &mut [f64], first: usize, cubic: [f64; 6]) {
    let [x0, inv_h, y0, d0, c2, c3] = cubic;
    for (t, o) in (first..first + out.len()).zip(out.iter_mut()) {
        let s = (t as i32 as f64 - x0) * inv_h;
        *o = y0 + s * (d0 + s * (c2 + s * c3));
    }
}

/// [`horner`] compiled for AVX2 (4 samples per instruction where x86-64's baseline has 2):
/// the same IEEE operations, no fused multiply-add (Rust never contracts), so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn horner_avx2(out: &mut [f64], first: usize, cubic: [f64; 6]) {
    horner(out, first, cubic)
}

#[cfg(test)]
mod tests;
