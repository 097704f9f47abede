//! Brent's derivative-free minimisation on a bracket (golden section + parabolic steps).
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
    mut f: impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
    tol_x: f64,
    max_iter: usize,
) -> (f64, f64) {
    const CGOLD: f64 = 0.381_966_011_250_105_1;
    let (mut a, mut b) = if a < b { (a, b) } else { (b, a) };
    let mut x = a + CGOLD * (b - a);
    let (mut w, mut v) = (x, x);
    let mut fx = f(x);
    let (mut fw, mut fv) = (fx, fx);
    let (mut d, mut e) = (0.0f64, 0.0f64);
    for _ in 0..max_iter {
        let xm = 0.5 * (a + b);
        let tol1 = tol_x * x.abs() + tol_x;
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
                if u - a < tol2 || b - u < tol2 {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_smooth_minima_quickly() {
        let mut calls = 0;
        let (x, fx) = minimize(
            |x| {
                calls += 1;
                (x - 0.3).powi(2) * 2.0 + 1.0 + 0.1 * (x - 0.3).powi(3)
            },
            0.0,
            1.0,
            1e-9,
            100,
        );
        assert!(
            (x - 0.3).abs() < 1e-7 && (fx - 1.0).abs() < 1e-13,
            "{x} {fx}"
        );
        assert!(calls < 40, "{calls} evaluations");
        let (x, _) = minimize(|x| x, 0.2, 0.9, 1e-9, 200);
        assert!((x - 0.2).abs() < 1e-7, "minimum at the end: {x}");
    }
}
