//! Brent's derivative-free minimisation on a bracket (golden section + parabolic steps): the
//! one line search of the crate (step-error extrema, carrier lines, gap effect parameters,
//! GCV choice of smoothing weights).
//!
//! Written here (no crate): argmin would bring a framework for a 50-line routine that must run
//! millions of times a second without allocating.

/// Minimises `f` on `[a, b]` by Brent's method; returns `(x_min, f(x_min))`.
///
/// Stops when the bracket is below `2 * (tol_x * |x| + tol_x)`; for a smooth minimum the value
/// error is then about `f'' * tol_x^2 / 2`. Golden-section steps guarantee linear convergence;
/// parabolic steps give superlinear convergence near a smooth minimum (~6-10 evaluations).
///
/// Reference: R. P. Brent, Algorithms for Minimization without Derivatives (1973), ch. 5.
/// Known bad cases: several local minima inside `[a, b]` (returns one of them); a minimum at
/// an end of the bracket is approached to within the tolerance (callers compare the ends).
pub fn minimize(
    f: impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
    tol_x: f64,
    max_iter: usize,
) -> (f64, f64) {
    let (a, b) = if a < b { (a, b) } else { (b, a) };
    let mut f = f;
    let x = a + CGOLD * (b - a);
    super::stop::check();
    let fx = f(x);
    let search = Search {
        tol: |x: f64| tol_x * x.abs() + tol_x,
        guard_ends: true,
        max_iter,
    };
    search.run(f, [a, b], (x, fx))
}

/// Minimises `f` over the points of `grid` (increasing), then by Brent's method between the
/// best grid point's neighbours, starting from that point; returns `(x_min, f(x_min))`.
///
/// The bracket stops shrinking below `2 * rel_tol * (bracket width)`, an absolute tolerance
/// fixed at the start (a parameter's scale is the grid's, not `|x|`), or after `max_iter`
/// evaluations past the grid. Unlike [`minimize`], the parabolic step may land next to the
/// bracket ends: those are grid points whose values are known to be higher.
///
/// Formula: Brent's parabolic interpolation with golden-section fallback on
/// `[grid[k-1], grid[k+1]]`, `k = argmin f(grid)` (first of equal minima).
/// Reference: R. P. Brent, Algorithms for Minimization without Derivatives (1973), ch. 5.
/// Known bad cases: a minimum narrower than the grid spacing elsewhere on the grid is
/// missed; an empty grid panics.
pub fn minimize_on_grid(
    mut f: impl FnMut(f64) -> f64,
    grid: &[f64],
    max_iter: usize,
    rel_tol: f64,
) -> (f64, f64) {
    let vals: Vec<f64> = grid
        .iter()
        .map(|&x| {
            super::stop::check();
            f(x)
        })
        .collect();
    let (k, _) =
        vals.iter().enumerate().fold(
            (0, f64::INFINITY),
            |acc, (i, &v)| if v < acc.1 { (i, v) } else { acc },
        );
    let (a, b) = (grid[k.saturating_sub(1)], grid[(k + 1).min(grid.len() - 1)]);
    let tol = rel_tol * (b - a).abs().max(1e-300);
    let search = Search {
        tol: |_: f64| tol,
        guard_ends: false,
        max_iter,
    };
    search.run(f, [a, b], (grid[k], vals[k]))
}

/// 1 - 1/φ: the golden-section step as a fraction of the larger bracket part.
const CGOLD: f64 = 0.381_966_011_250_105_1;

/// The settings of one Brent search (shared by [`minimize`] and [`minimize_on_grid`]).
struct Search<T: Fn(f64) -> f64> {
    /// Tolerance `tol1` on x at the current best point.
    tol: T,
    /// Keep trial points at least `2 tol1` from the bracket ends (Brent's original rule).
    guard_ends: bool,
    max_iter: usize,
}

impl<T: Fn(f64) -> f64> Search<T> {
    /// Brent's loop on `[a, b]` (a < b) from the best point so far `(x, f(x))`.
    fn run(
        &self,
        mut f: impl FnMut(f64) -> f64,
        [mut a, mut b]: [f64; 2],
        (mut x, mut fx): (f64, f64),
    ) -> (f64, f64) {
        let (mut w, mut v) = (x, x);
        let (mut fw, mut fv) = (fx, fx);
        let (mut d, mut e) = (0.0f64, 0.0f64);
        for _ in 0..self.max_iter {
            let xm = 0.5 * (a + b);
            let tol1 = (self.tol)(x);
            let tol2 = 2.0 * tol1;
            if (x - xm).abs() <= tol2 - 0.5 * (b - a) {
                break;
            }
            let mut golden = true;
            if e.abs() > tol1 {
                // Parabola through (v, fv), (w, fw), (x, fx).
                let r = (x - w) * (fx - fv);
                let mut q = (x - v) * (fx - fw);
                let mut p = (x - v) * q - (x - w) * r;
                q = 2.0 * (q - r);
                if q > 0.0 {
                    p = -p;
                }
                q = q.abs();
                let etemp = e;
                e = d;
                if p.abs() < (0.5 * q * etemp).abs() && p > q * (a - x) && p < q * (b - x) {
                    d = p / q;
                    let u = x + d;
                    if self.guard_ends && (u - a < tol2 || b - u < tol2) {
                        d = if xm >= x { tol1 } else { -tol1 };
                    }
                    golden = false;
                }
            }
            if golden {
                e = if x >= xm { a - x } else { b - x };
                d = CGOLD * e;
            }
            let u = if d.abs() >= tol1 {
                x + d
            } else {
                x + tol1.copysign(d)
            };
            super::stop::check();
            let fu = f(u);
            if fu <= fx {
                if u >= x {
                    a = x;
                } else {
                    b = x;
                }
                (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
            } else {
                if u < x {
                    a = u;
                } else {
                    b = u;
                }
                if fu <= fw || w == x {
                    (v, fv, w, fw) = (w, fw, u, fu);
                } else if fu <= fv || v == x || v == w {
                    (v, fv) = (u, fu);
                }
            }
        }
        (x, fx)
    }
}

#[cfg(test)]
mod tests;
