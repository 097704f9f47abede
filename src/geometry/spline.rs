//! Interpolating cubic spline through 3-D points (not-a-knot ends), the CC-curve model of the
//! step-error computation (Zhang et al. 2023, "Geometry principle": the CC curve between two
//! contact points, known by discrete points, is interpolated).
//!
//! Written here (no crate): splines on 3-D points with reusable buffers, evaluated millions of
//! times a second, are 150 lines; the interpolation crates allocate per call or are 1-D only.

use super::error::{Error, Result};
use crate::numeric::tridiag::Tridiagonal;

/// How the spline parameter `t` in [0, 1] is spread over the points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Parameterization {
    /// `t_k = k / (m - 1)`: right for points sampled at equal parameter steps (Zhang et al. 2023's
    /// iso-parametric samples).
    Uniform,
    /// `t_k` proportional to the cumulative chord length: right for unevenly spaced points.
    ChordLength,
}

/// A C2 cubic spline `Q(t)`, `t` in [0, 1], through points `p_k` at knots `t_k`, with
/// not-a-knot end conditions (third derivative continuous at `t_1` and `t_{m-2}`), so a cubic
/// is reproduced exactly and the interpolation error is O(h^4) up to the ends.
/// With 3 points it is the parabola through them.
#[derive(Clone, Debug, Default)]
pub struct CubicSpline3 {
    t: Vec<f64>,
    p: Vec<[f64; 3]>,
    /// Second derivatives d2Q/dt2 at the knots.
    d2: Vec<[f64; 3]>,
    /// Thomas factors of the general-knot system (kept to refit without allocating).
    tri: Tridiagonal,
    /// Uniform knots: the twisted elimination's factors, which depend on the row only.
    inv_denom: Vec<f64>,
    /// m when the knots are uniform (then `t` is kept between fits), else 0.
    factored_m: usize,
}

impl CubicSpline3 {
    /// An empty spline whose buffers [`CubicSpline3::fit`] fills (reuse it in loops).
    pub fn new() -> Self {
        Self::default()
    }

    /// The spline through `points` (m >= 3, consecutive points distinct).
    pub fn through(points: &[[f64; 3]], param: Parameterization) -> Result<Self> {
        let mut s = Self::new();
        s.fit(points, param)?;
        Ok(s)
    }

    /// Refits this spline through `points`, reusing its buffers.
    ///
    /// Solves the tridiagonal system for the knot second derivatives `M_k`:
    /// `h_{k-1} M_{k-1} + 2 (h_{k-1} + h_k) M_k + h_k M_{k+1} = 6 (Δp_k / h_k - Δp_{k-1} / h_{k-1})`,
    /// with `M_0`, `M_{m-1}` eliminated by the not-a-knot conditions. Errors: m < 3,
    /// non-finite points, coincident consecutive points (chord-length parameterization).
    pub fn fit(&mut self, points: &[[f64; 3]], param: Parameterization) -> Result<()> {
        let m = points.len();
        if m < 3 {
            return Err(Error::TooFewPoints {
                what: "a cubic spline",
                min: 3,
                got: m,
            });
        }
        self.p.clear();
        self.p.extend_from_slice(points);
        // Every entry is overwritten by the solve.
        self.d2.resize(m, [0.0; 3]);
        match param {
            // Uniform knots depend on m only: kept from the previous fit with the same m.
            Parameterization::Uniform if self.factored_m == m => {}
            Parameterization::Uniform => {
                self.t.clear();
                let inv = 1.0 / (m - 1) as f64;
                self.t.extend((0..m).map(|k| k as f64 * inv));
                self.factored_m = m;
            }
            Parameterization::ChordLength => {
                self.factored_m = 0;
                self.t.clear();
                let mut acc = 0.0;
                self.t.push(0.0);
                for k in 1..m {
                    let d = crate::numeric::vec3::norm(crate::numeric::vec3::sub(
                        points[k],
                        points[k - 1],
                    ));
                    if d.is_nan() || d <= 0.0 {
                        return Err(Error::DuplicatePoints { index: k - 1 });
                    }
                    acc += d;
                    self.t.push(acc);
                }
                let inv = 1.0 / acc;
                self.t.iter_mut().for_each(|t| *t *= inv);
                self.t[m - 1] = 1.0;
            }
        }
        if matches!(param, Parameterization::Uniform) && m >= 4 {
            self.solve_uniform();
        } else {
            self.solve_general();
        }
        Ok(())
    }

    /// The system for uniform knots (h = 1/(m-1)) in `S_k = h^2 M_k / 6`: the not-a-knot rows
    /// decouple (`S_1 = Δ²p_1 / 6`, `S_{m-2} = Δ²p_{m-2} / 6`, `Δ²p_k = p_{k+1} - 2 p_k + p_{k-1}`)
    /// and the q = m - 4 rows between are `S_{k-1} + 4 S_k + S_{k+1} = Δ²p_k`. They are solved
    /// from both ends at once (a twisted Thomas factorisation: two elimination chains of q/2
    /// rows meeting at the middle row, then two substitution chains outwards), which halves the
    /// dependency chains of the plain sweep. The elimination factors `f_0 = 1/4`,
    /// `f_i = 1/(4 - f_{i-1})` do not depend on m (kept, grown on demand).
    /// Then `S_0 = 2 S_1 - S_2`, `S_{m-1} = 2 S_{m-2} - S_{m-3}`, `M = 6 S / h^2`.
    /// Same solution as [`CubicSpline3::solve_general`] (a unit test checks), no divisions.
    fn solve_uniform(&mut self) {
        let m = self.p.len();
        let q = m - 4; // unknowns S_2..S_{m-3}, rows i = k - 2
        if self.inv_denom.len() < q {
            self.inv_denom.clear();
            let mut f = 0.0;
            self.inv_denom.extend((0..q).map(|_| {
                f = 1.0 / (4.0 - f);
                f
            }));
        }
        let p = &self.p[..m];
        let d2 = &mut self.d2[..m];
        let f = &self.inv_denom[..q];
        let dd = |w: &[[f64; 3]]| -> [f64; 3] {
            std::array::from_fn(|d| w[2][d] - 2.0 * w[1][d] + w[0][d])
        };
        let sixth = 1.0 / 6.0;
        let s1 = dd(&p[0..3]).map(|v| v * sixth);
        let sl = dd(&p[m - 3..m]).map(|v| v * sixth);
        if q > 0 {
            // Rows 0..h-1 eliminated downwards (x_i + f_i x_{i+1} = y_i), rows q-1..h+1
            // upwards (x_i + f_{q-1-i} x_{i-1} = z_i), the known S_1 / S_{m-2} entering as
            // y_{-1} / z_q; y, z stored in the rows' own slots d2[i + 2].
            let h = q / 2;
            let rows = &mut d2[2..m - 2];
            let rhs = &p[1..m - 1]; // row i: Δ² over rhs[i..i + 3]
            let mut y = s1;
            for (i, (out, &fi)) in rows[..h].iter_mut().zip(f).enumerate() {
                let r = dd(&rhs[i..i + 3]);
                y = std::array::from_fn(|d| (r[d] - y[d]) * fi);
                *out = y;
            }
            let mut z = sl;
            for (i, (out, &fi)) in rows[h + 1..].iter_mut().rev().zip(f).enumerate() {
                let r = dd(&rhs[q - 1 - i..q + 2 - i]);
                z = std::array::from_fn(|d| (r[d] - z[d]) * fi);
                *out = z;
            }
            let f_top = if h > 0 { f[h - 1] } else { 0.0 };
            let f_bot = if q - 1 - h > 0 { f[q - 2 - h] } else { 0.0 };
            let inv_mid = 1.0 / (4.0 - f_top - f_bot);
            let r = dd(&rhs[h..h + 3]);
            let xm: [f64; 3] = std::array::from_fn(|d| (r[d] - y[d] - z[d]) * inv_mid);
            rows[h] = xm;
            let mut x = xm;
            for (out, &fi) in rows[..h].iter_mut().rev().zip(f[..h].iter().rev()) {
                x = std::array::from_fn(|d| out[d] - fi * x[d]);
                *out = x;
            }
            let mut x = xm;
            let nb = q - 1 - h;
            for (out, &fi) in rows[h + 1..].iter_mut().zip(f[..nb].iter().rev()) {
                x = std::array::from_fn(|d| out[d] - fi * x[d]);
                *out = x;
            }
        }
        d2[1] = s1;
        d2[m - 2] = sl;
        let scale = 6.0 * ((m - 1) * (m - 1)) as f64;
        let (s2, s3) = (d2[2], d2[m - 3]);
        d2[0] = std::array::from_fn(|d| 2.0 * s1[d] - s2[d]);
        d2[m - 1] = std::array::from_fn(|d| 2.0 * sl[d] - s3[d]);
        for v in d2.iter_mut() {
            *v = v.map(|x| x * scale);
        }
    }

    /// The system for any knots (see [`CubicSpline3::fit`]), by the Thomas algorithm
    /// ([`Tridiagonal`]).
    fn solve_general(&mut self) {
        let m = self.p.len();
        let (t, p) = (&self.t, &self.p);
        let h = |k: usize| t[k + 1] - t[k];
        if m == 3 {
            let slope = |k: usize, d: usize| (p[k + 1][d] - p[k][d]) / h(k);
            for d in 0..3 {
                let v = 2.0 * (slope(1, d) - slope(0, d)) / (t[2] - t[0]);
                for k in 0..3 {
                    self.d2[k][d] = v;
                }
            }
            return;
        }
        // Unknowns M_1..M_{m-2}: n = m - 2 rows; row i is knot i + 1.
        let n = m - 2;
        let (h0, h1) = (h(0), h(1));
        let (hl, hl1) = (h(m - 2), h(m - 3)); // last and second-to-last intervals
        self.tri.clear();
        for i in 0..n {
            let k = i + 1;
            let (hk1, hk) = (h(k - 1), h(k));
            let mut lower = hk1;
            let mut diag = 2.0 * (hk1 + hk);
            let mut upper = hk;
            if i == 0 {
                diag += h0 + h0 * h0 / h1;
                upper -= h0 * h0 / h1;
                lower = 0.0;
            }
            if i == n - 1 {
                diag += hl + hl * hl / hl1;
                lower -= hl * hl / hl1;
                upper = 0.0;
            }
            self.tri.push_row(lower, diag, upper);
        }
        let mut slope_prev: [f64; 3] = std::array::from_fn(|d| (p[1][d] - p[0][d]) / h(0));
        for k in 1..=n {
            for d in 0..3 {
                let slope = (p[k + 1][d] - p[k][d]) / h(k);
                self.d2[k][d] = 6.0 * (slope - slope_prev[d]);
                slope_prev[d] = slope;
            }
        }
        self.tri.solve_in_place(&mut self.d2[1..=n]);
        for d in 0..3 {
            let (m1, m2) = (self.d2[1][d], self.d2[2][d]);
            self.d2[0][d] = m1 * (1.0 + h0 / h1) - (h0 / h1) * m2;
            let (a, b) = (self.d2[m - 2][d], self.d2[m - 3][d]);
            self.d2[m - 1][d] = a * (1.0 + hl / hl1) - (hl / hl1) * b;
        }
    }

    /// Knot parameters `t_k` in [0, 1].
    pub fn knots(&self) -> &[f64] {
        &self.t
    }

    /// Interpolated points `p_k`.
    pub fn points(&self) -> &[[f64; 3]] {
        &self.p
    }

    /// Index k of the interval [t_k, t_{k+1}] holding `t` (clamped to the ends).
    #[inline]
    pub fn interval(&self, t: f64) -> usize {
        let n = self.t.len();
        if self.factored_m == n {
            // Uniform knots: the interval is a multiplication away.
            let k = (t * (n - 1) as f64) as isize;
            return k.clamp(0, n as isize - 2) as usize;
        }
        // partition_point: first knot > t.
        let k = self.t.partition_point(|&x| x <= t);
        k.clamp(1, n - 1) - 1
    }

    /// Position `Q(t)` on interval `k` (mm).
    #[inline]
    pub fn eval_in(&self, k: usize, t: f64) -> [f64; 3] {
        let h = self.t[k + 1] - self.t[k];
        let b = (t - self.t[k]) / h;
        let a = 1.0 - b;
        let ca = (a * a * a - a) * h * h / 6.0;
        let cb = (b * b * b - b) * h * h / 6.0;
        let (p0, p1, m0, m1) = (self.p[k], self.p[k + 1], self.d2[k], self.d2[k + 1]);
        [
            a * p0[0] + b * p1[0] + ca * m0[0] + cb * m1[0],
            a * p0[1] + b * p1[1] + ca * m0[1] + cb * m1[1],
            a * p0[2] + b * p1[2] + ca * m0[2] + cb * m1[2],
        ]
    }

    /// Position `Q(t)`, `t` in [0, 1] (mm).
    #[inline]
    pub fn eval(&self, t: f64) -> [f64; 3] {
        self.eval_in(self.interval(t), t)
    }

    /// First derivative `dQ/dt` (mm per unit t).
    pub fn eval_d1(&self, t: f64) -> [f64; 3] {
        let k = self.interval(t);
        let h = self.t[k + 1] - self.t[k];
        let b = (t - self.t[k]) / h;
        let a = 1.0 - b;
        let ca = -(3.0 * a * a - 1.0) * h / 6.0;
        let cb = (3.0 * b * b - 1.0) * h / 6.0;
        let (p0, p1, m0, m1) = (self.p[k], self.p[k + 1], self.d2[k], self.d2[k + 1]);
        std::array::from_fn(|d| (p1[d] - p0[d]) / h + ca * m0[d] + cb * m1[d])
    }

    /// Second derivative `d2Q/dt2` (mm per unit t squared): linear between knots.
    #[inline]
    pub fn eval_d2(&self, t: f64) -> [f64; 3] {
        let k = self.interval(t);
        let h = self.t[k + 1] - self.t[k];
        let b = (t - self.t[k]) / h;
        let a = 1.0 - b;
        std::array::from_fn(|d| a * self.d2[k][d] + b * self.d2[k + 1][d])
    }

    /// Second derivatives at the knots.
    pub fn knot_d2(&self) -> &[[f64; 3]] {
        &self.d2
    }

    /// The cubic on interval `k` in its local parameter: `Q(t) = c0 + c1 b + c2 b^2 + c3 b^3`
    /// with `b = (t - t_k) / h_k` in [0, 1], `h_k = t_{k+1} - t_k` (mm).
    ///
    /// From the knot form `Q = a p_k + b p_{k+1} + h_k^2/6 ((a^3 - a) M_k + (b^3 - b) M_{k+1})`,
    /// `a = 1 - b`: with `m_j = h_k^2 M_j / 6`, `c0 = p_k`, `c1 = p_{k+1} - p_k - 2 m_k - m_{k+1}`,
    /// `c2 = 3 m_k`, `c3 = m_{k+1} - m_k`. Panics when `k + 1` is not a knot.
    #[inline]
    pub fn piece(&self, k: usize) -> [[f64; 3]; 4] {
        let h = self.t[k + 1] - self.t[k];
        let h26 = h * h / 6.0;
        let (p0, p1, d0, d1) = (self.p[k], self.p[k + 1], self.d2[k], self.d2[k + 1]);
        let mut c = [[0.0; 3]; 4];
        for d in 0..3 {
            let (m0, m1) = (d0[d] * h26, d1[d] * h26);
            c[0][d] = p0[d];
            c[1][d] = p1[d] - p0[d] - 2.0 * m0 - m1;
            c[2][d] = 3.0 * m0;
            c[3][d] = m1 - m0;
        }
        c
    }
}

#[cfg(test)]
mod tests;
