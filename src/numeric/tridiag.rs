//! The tridiagonal solve (Thomas algorithm) behind the cubic splines: the not-a-knot spline of
//! the decomposition envelopes, the 3-D CC-curve spline of the step error and the natural
//! path spline of the contour error.
//!
//! Written here (no crate): the Thomas algorithm is twenty lines, and the splines need it on
//! reusable buffers (the step-error spline refits millions of times a second) with scalar or
//! 3-vector right-hand sides; nalgebra has no banded solver.

/// A right-hand side value: a scalar or a fixed-size vector solved component by component.
pub trait Rhs: Copy {
    /// `(self - s * other) * inv`, component-wise.
    fn eliminate(self, s: f64, other: Self, inv: f64) -> Self;
    /// `self - s * other`, component-wise.
    fn sub_scaled(self, s: f64, other: Self) -> Self;
    /// `self * s`, component-wise.
    fn scaled(self, s: f64) -> Self;
}

impl Rhs for f64 {
    #[inline(always)]
    fn eliminate(self, s: f64, other: Self, inv: f64) -> Self {
        (self - s * other) * inv
    }
    #[inline(always)]
    fn sub_scaled(self, s: f64, other: Self) -> Self {
        self - s * other
    }
    #[inline(always)]
    fn scaled(self, s: f64) -> Self {
        self * s
    }
}

impl<const D: usize> Rhs for [f64; D] {
    #[inline(always)]
    fn eliminate(self, s: f64, other: Self, inv: f64) -> Self {
        std::array::from_fn(|d| (self[d] - s * other[d]) * inv)
    }
    #[inline(always)]
    fn sub_scaled(self, s: f64, other: Self) -> Self {
        std::array::from_fn(|d| self[d] - s * other[d])
    }
    #[inline(always)]
    fn scaled(self, s: f64) -> Self {
        self.map(|v| v * s)
    }
}

/// The Thomas factorisation of a tridiagonal matrix, built row by row; keep one and
/// [`Tridiagonal::clear`] it to refit without allocating.
///
/// Row i reads `lower_i x_{i-1} + diag_i x_i + upper_i x_{i+1} = r_i` (`lower_0` and the last
/// row's `upper` are ignored).
///
/// Formula: `c_i = upper_i / (diag_i - lower_i c_{i-1})` (`c_{-1} = 0`); forward
/// `y_i = (r_i - lower_i y_{i-1}) / (diag_i - lower_i c_{i-1})`, backward `x_i = y_i - c_i x_{i+1}`.
/// The reciprocals of the pivots are stored, so a solve does no division.
/// Reference: L. H. Thomas (1949); Golub & Van Loan, Matrix Computations (4th ed., 2013), §4.3.
/// Known bad cases: no pivoting, so the matrix must be diagonally dominant (every spline
/// system here is) or at least have nonzero pivots; a zero pivot gives infinities.
#[derive(Clone, Debug, Default)]
pub struct Tridiagonal {
    lower: Vec<f64>,
    /// `c_i`: the eliminated super-diagonal.
    c: Vec<f64>,
    /// `1 / (diag_i - lower_i c_{i-1})`.
    inv: Vec<f64>,
}

impl Tridiagonal {
    /// An empty factorisation.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets every row, keeping the buffers.
    pub fn clear(&mut self) {
        self.lower.clear();
        self.c.clear();
        self.inv.clear();
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.inv.len()
    }

    /// True when no row has been pushed.
    pub fn is_empty(&self) -> bool {
        self.inv.is_empty()
    }

    /// Appends the next row and eliminates it.
    #[inline]
    pub fn push_row(&mut self, lower: f64, diag: f64, upper: f64) {
        let c_prev = self.c.last().copied().unwrap_or(0.0);
        let inv = 1.0 / (diag - lower * c_prev);
        self.c.push(upper * inv);
        self.lower.push(lower);
        self.inv.push(inv);
    }

    /// Solves in place: `rhs[i]` is row i's right-hand side and becomes `x_i`.
    /// Panics if `rhs` does not have [`Tridiagonal::len`] rows.
    pub fn solve_in_place<T: Rhs>(&self, rhs: &mut [T]) {
        let n = self.len();
        assert_eq!(rhs.len(), n, "one right-hand side per row");
        if n == 0 {
            return;
        }
        rhs[0] = rhs[0].scaled(self.inv[0]);
        for i in 1..n {
            rhs[i] = rhs[i].eliminate(self.lower[i], rhs[i - 1], self.inv[i]);
        }
        for i in (0..n - 1).rev() {
            rhs[i] = rhs[i].sub_scaled(self.c[i], rhs[i + 1]);
        }
    }
}

/// Solves one tridiagonal system in place (see [`Tridiagonal`]); `lower[0]` and
/// `upper[n-1]` are unused. Allocates the factors; keep a [`Tridiagonal`] in loops.
pub fn solve<T: Rhs>(lower: &[f64], diag: &[f64], upper: &[f64], rhs: &mut [T]) {
    let mut t = Tridiagonal::new();
    for i in 0..diag.len() {
        t.push_row(if i == 0 { 0.0 } else { lower[i] }, diag[i], upper[i]);
    }
    t.solve_in_place(rhs);
}

#[cfg(test)]
mod tests;
