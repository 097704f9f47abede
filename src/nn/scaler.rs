//! Z-score normalisation (Zhang et al. 2023 eq. 7).

use super::error::{Error, Result, check_finite};

/// Per-column z-score scaler: `x_scaled = (x - mu) / S` with the sample standard deviation
/// `S = sqrt(sum (x - mu)^2 / (n - 1))`.
///
/// Reference: Zhang et al. 2023 eq. 7. Known bad case: a constant column (S = 0, e.g. a fixed tool
/// radius) would divide by zero; its S is set to 1 so the column just becomes 0.
#[derive(Clone, Debug, PartialEq)]
pub struct ZScore {
    /// Column means (units of the column).
    pub mean: Vec<f64>,
    /// Column standard deviations (units of the column), 1 for constant columns.
    pub std: Vec<f64>,
}

impl ZScore {
    /// The identity scaler on `cols` columns (mean 0, std 1).
    pub fn identity(cols: usize) -> Self {
        ZScore {
            mean: vec![0.0; cols],
            std: vec![1.0; cols],
        }
    }

    /// Fits mean and sample standard deviation of each column of a row-major matrix.
    ///
    /// Errors: `cols == 0`, a length that is not a multiple of `cols`, fewer than 2 rows,
    /// non-finite values.
    pub fn fit(x: &[f64], cols: usize) -> Result<Self> {
        if cols == 0 || x.len() % cols != 0 {
            return Err(Error::Shape {
                what: "z-score data (multiple of columns)",
                expected: cols,
                got: x.len(),
            });
        }
        let n = x.len() / cols;
        if n < 2 {
            return Err(Error::TooFewSamples {
                what: "z-score fit",
                min: 2,
                got: n,
            });
        }
        check_finite("z-score data", x)?;
        let mut mean = vec![0.0; cols];
        for row in x.chunks_exact(cols) {
            for (m, v) in mean.iter_mut().zip(row) {
                *m += v;
            }
        }
        mean.iter_mut().for_each(|m| *m /= n as f64);
        let mut var = vec![0.0; cols];
        for row in x.chunks_exact(cols) {
            for ((s, v), m) in var.iter_mut().zip(row).zip(&mean) {
                *s += (v - m) * (v - m);
            }
        }
        let std = var
            .into_iter()
            .zip(&mean)
            .map(|(s, m)| {
                let sd = (s / (n - 1) as f64).sqrt();
                // Relative threshold: a column constant up to rounding is constant.
                if sd <= 1e-12 * m.abs().max(1e-300) || sd == 0.0 {
                    1.0
                } else {
                    sd
                }
            })
            .collect();
        Ok(ZScore { mean, std })
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.mean.len()
    }

    /// Scales a row-major matrix in place: `x = (x - mu) / S`, eq. (7).
    pub fn transform_in_place(&self, x: &mut [f64]) {
        let c = self.cols();
        for row in x.chunks_exact_mut(c) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = (*v - m) / s;
            }
        }
    }

    /// Returns a scaled copy of a row-major matrix.
    pub fn transform(&self, x: &[f64]) -> Vec<f64> {
        let mut out = x.to_vec();
        self.transform_in_place(&mut out);
        out
    }

    /// Undoes the scaling in place: `x = x * S + mu`.
    pub fn inverse_in_place(&self, x: &mut [f64]) {
        let c = self.cols();
        for row in x.chunks_exact_mut(c) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = *v * s + m;
            }
        }
    }
}

#[cfg(test)]
mod tests;
