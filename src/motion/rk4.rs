//! Classical RK4 integration of a 4-state axis driven by a first-order-hold command.
//!
//! Used as the slow, obvious reference against which the exact discretization in
//! [`crate::motion::servo`] is checked, and by the gap self-check's independent truth plants
//! (whose nonlinear friction has no exact discretization).

/// Integrates `d(state)/dt = deriv(state, r(t), dr/dt)` with RK4, `substeps` steps per period.
///
/// The command is read as openapi.yaml `POST /v1/machines/{machine}/gap-diagnosis` says: sample `i`
/// at `t = i·period_s`, straight lines between samples (so `dr/dt` is the segment's slope), and the
/// axis starts at rest at `command[0]` (state `[command[0], 0, 0, 0]`: position mm, velocity
/// mm/s, acceleration mm/s², velocity-loop integral mm). Returns the position (state 0) at every
/// sample, `command.len()` values (empty for an empty command).
///
/// Reference: classical fourth-order Runge–Kutta; global error O(h⁴), h = period_s/substeps.
/// Bad cases: stiff dynamics (a current-loop lag or friction slope much faster than h) need
/// more sub-steps; `substeps = 0` is treated as 1.
pub fn rk4_first_order_hold(
    command: &[f64],
    period_s: f64,
    substeps: usize,
    deriv: impl Fn([f64; 4], f64, f64) -> [f64; 4],
) -> Vec<f64> {
    let Some(&first) = command.first() else {
        return Vec::new();
    };
    let sub = substeps.max(1);
    let h = period_s / sub as f64;
    let add = |a: [f64; 4], b: [f64; 4], f: f64| {
        [
            a[0] + f * b[0],
            a[1] + f * b[1],
            a[2] + f * b[2],
            a[3] + f * b[3],
        ]
    };
    let mut st = [first, 0.0, 0.0, 0.0];
    let mut out = Vec::with_capacity(command.len());
    out.push(first);
    for w in command.windows(2) {
        let s = (w[1] - w[0]) / period_s;
        let r = |t: f64| w[0] + s * t;
        for k in 0..sub {
            let t0 = k as f64 * h;
            let k1 = deriv(st, r(t0), s);
            let k2 = deriv(add(st, k1, h / 2.0), r(t0 + h / 2.0), s);
            let k3 = deriv(add(st, k2, h / 2.0), r(t0 + h / 2.0), s);
            let k4 = deriv(add(st, k3, h), r(t0 + h), s);
            for i in 0..4 {
                st[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        out.push(st[0]);
    }
    out
}

#[cfg(test)]
mod tests;
