//! The one optimiser: projected Levenberg–Marquardt (Marquardt's diagonal scaling) on the
//! objective's residuals, with a finite-difference Jacobian coloured by feature windows.
//!
//! A feature changes the error only within its path-length window (the stretch its pieces
//! cover and the servo's settling after it), so features whose windows do not overlap are
//! perturbed in the same simulation and each column is read from its own window's rows
//! (Curtis–Powell–Reid colouring). A Jacobian costs (colours × 4) evaluations, not one per
//! parameter. The time residual is global; each feature's share of it is read from the
//! nominal run's time spent in its window. Bounds are kept by projection: a step is
//! clipped into the box, and a parameter on its bound whose gradient pushes outwards is
//! held for that step.

use std::ops::Range;

use nalgebra::{DMatrix, DVector};

use super::Error;
use super::objective::Eval;
use super::shape::Shape;

/// The optimiser stops when an accepted step lowers the cost by less than this share
/// (0.1 %): the figures then change in their third digit at most.
pub const CONVERGED: f64 = 1e-3;

/// Damping trials per iteration before the optimiser gives up (λ grows 4× a trial: 4⁶ ≈
/// 4,000× the damping, a step of a gradient descent's length).
pub const TRIALS: usize = 6;

/// Where each feature's columns live.
pub struct Layout {
    /// Residual rows of each feature's window.
    pub rows: Vec<Vec<Range<usize>>>,
    /// Bins of each feature's window.
    pub bins: Vec<Range<usize>>,
}

/// What the optimiser found.
pub struct Solved {
    /// The parameters.
    pub x: Vec<f64>,
    /// Their objective.
    pub eval: Eval,
    /// Evaluations of the objective (each simulates every model once).
    pub evaluations: usize,
    /// Iterations (Jacobians).
    pub iterations: usize,
    /// True when it stopped because no damping gave a lower cost.
    pub stalled: bool,
}

/// Colours of the features: features of one colour have disjoint bin windows.
pub(super) fn colours(bins: &[Range<usize>]) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..bins.len()).collect();
    order.sort_by_key(|&k| bins[k].start);
    let mut out: Vec<(usize, Vec<usize>)> = Vec::new();
    for k in order {
        match out.iter_mut().find(|(end, _)| *end <= bins[k].start) {
            Some((end, v)) => {
                *end = bins[k].end;
                v.push(k);
            }
            None => out.push((bins[k].end, vec![k])),
        }
    }
    out.into_iter().map(|(_, v)| v).collect()
}

/// Sparse column: (row, value) in row order, and the time row's value.
type Column = (Vec<(usize, f64)>, f64);

/// Σ a·b over the rows both sparse columns hold.
pub(super) fn dot_sparse(a: &[(usize, f64)], b: &[(usize, f64)]) -> f64 {
    let (mut i, mut j, mut s) = (0, 0, 0.0);
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                s += a[i].1 * b[j].1;
                i += 1;
                j += 1;
            }
        }
    }
    s
}

/// Minimises Σ r² of `eval(x)` over the box of `shape` from `x0` (within the box), at most
/// `max_iterations` Jacobians.
pub fn solve(
    shape: &Shape,
    layout: &Layout,
    x0: &[f64],
    max_iterations: usize,
    eval: &dyn Fn(&[f64]) -> Result<Eval, Error>,
) -> Result<Solved, Error> {
    let np = shape.len();
    let mut x = x0.to_vec();
    let mut cur = eval(&x)?;
    let mut evaluations = 1;
    let mut iterations = 0;
    let mut stalled = false;
    let mut lambda = 1e-2;
    let cols = colours(&layout.bins);
    let owner: Vec<usize> = (0..shape.features.len())
        .flat_map(|k| std::iter::repeat_n(k, shape.features[k].size()))
        .collect();
    while iterations < max_iterations && np > 0 {
        iterations += 1;
        // The Jacobian, one colour and parameter slot at a time.
        let mut jac: Vec<Column> = vec![(Vec::new(), 0.0); np];
        for colour in &cols {
            crate::numeric::stop::check();
            for slot in 0..4 {
                let members: Vec<usize> = colour
                    .iter()
                    .copied()
                    .filter(|&k| shape.features[k].size() > slot)
                    .filter(|&k| {
                        let p = shape.offset[k] + slot;
                        shape.hi[p] > shape.lo[p]
                    })
                    .collect();
                if members.is_empty() {
                    continue;
                }
                let mut xp = x.clone();
                let mut h = vec![0.0; np];
                for &k in &members {
                    let p = shape.offset[k] + slot;
                    let step = shape.step[p].min(shape.hi[p] - shape.lo[p]);
                    h[p] = if x[p] + step <= shape.hi[p] {
                        step
                    } else {
                        -step
                    };
                    xp[p] = x[p] + h[p];
                }
                let e = eval(&xp)?;
                evaluations += 1;
                for &k in &members {
                    let p = shape.offset[k] + slot;
                    let mut col = Vec::new();
                    for rows in &layout.rows[k] {
                        for row in rows.clone() {
                            let d = (e.r[row] - cur.r[row]) / h[p];
                            if d != 0.0 {
                                col.push((row, d));
                            }
                        }
                    }
                    let dt: f64 = layout.bins[k]
                        .clone()
                        .map(|b| e.time[b] - cur.time[b])
                        .sum();
                    jac[p] = (col, cur.time_slope * dt / h[p]);
                }
            }
        }
        // Normal equations with the time row.
        let last = cur.r.len() - 1;
        let mut hm = DMatrix::<f64>::zeros(np, np);
        let mut g = DVector::<f64>::zeros(np);
        for i in 0..np {
            let (ci, ti) = &jac[i];
            g[i] = ci.iter().map(|(r, v)| v * cur.r[*r]).sum::<f64>() + ti * cur.r[last];
            for j in i..np {
                let (cj, tj) = &jac[j];
                let overlap = owner[i] == owner[j]
                    || (layout.bins[owner[i]].start < layout.bins[owner[j]].end
                        && layout.bins[owner[j]].start < layout.bins[owner[i]].end);
                let mut v = ti * tj;
                if overlap {
                    v += dot_sparse(ci, cj);
                }
                hm[(i, j)] = v;
                hm[(j, i)] = v;
            }
        }
        // Parameters held this step: fixed, or on a bound the gradient pushes through.
        let free: Vec<usize> = (0..np)
            .filter(|&p| {
                shape.hi[p] > shape.lo[p]
                    && !(x[p] <= shape.lo[p] && g[p] > 0.0)
                    && !(x[p] >= shape.hi[p] && g[p] < 0.0)
                    && hm[(p, p)] > 0.0
            })
            .collect();
        if free.is_empty() {
            break;
        }
        let nf = free.len();
        let mut accepted = false;
        for _ in 0..TRIALS {
            let mut a = DMatrix::<f64>::zeros(nf, nf);
            let mut b = DVector::<f64>::zeros(nf);
            for (u, &p) in free.iter().enumerate() {
                b[u] = -g[p];
                for (v, &q) in free.iter().enumerate() {
                    a[(u, v)] = hm[(p, q)];
                }
                a[(u, u)] += lambda * hm[(p, p)] + 1e-12;
            }
            let Some(ch) = a.cholesky() else {
                lambda *= 4.0;
                continue;
            };
            let dx = ch.solve(&b);
            let mut xn = x.clone();
            for (u, &p) in free.iter().enumerate() {
                xn[p] = (x[p] + dx[u]).clamp(shape.lo[p], shape.hi[p]);
            }
            let e = eval(&xn)?;
            evaluations += 1;
            let (c0, c1) = (cur.cost(), e.cost());
            if c1 < c0 {
                x = xn;
                cur = e;
                lambda = (lambda / 3.0).max(1e-7);
                accepted = true;
                if (c0 - c1) < CONVERGED * c0 {
                    return Ok(Solved {
                        x,
                        eval: cur,
                        evaluations,
                        iterations,
                        stalled: false,
                    });
                }
                break;
            }
            lambda *= 4.0;
        }
        if !accepted {
            stalled = true;
            break;
        }
    }
    Ok(Solved {
        x,
        eval: cur,
        evaluations,
        iterations,
        stalled,
    })
}
