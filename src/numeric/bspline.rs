//! Uniform cubic B-splines: the one basis evaluation shared by the cores' spline models
//! (decomposition carriers, volumetric P-spline residual, ISO 230-1 error motions).

/// The four nonzero uniform cubic B-splines at `q` on `[a, b]` cut into `pieces` equal
/// intervals: the index of the first of them and their values (which sum to 1).
/// `q` outside `[a, b]` is clamped to it; `pieces ≥ 1`.
///
/// Formula: the cardinal cubic B-spline pieces (1−t)³/6, (3t³−6t²+4)/6, (−3t³+3t²+3t+1)/6,
/// t³/6 at the local coordinate t ∈ [0, 1) (de Boor, A Practical Guide to Splines, ch. IX).
pub fn uniform_cubic(q: f64, [a, b]: [f64; 2], pieces: usize) -> (usize, [f64; 4]) {
    let u = if b > a {
        ((q - a) / (b - a) * pieces as f64).clamp(0.0, pieces as f64)
    } else {
        0.0
    };
    // u ≥ 0 (or NaN, which both casts send to 0), so truncation is the floor: no libm call
    // (x86-64's baseline has no rounding instruction).
    let j = (u as usize).min(pieces - 1);
    let t = u - j as f64;
    let s = 1.0 - t;
    (
        j,
        [
            s * s * s / 6.0,
            (3.0 * t * t * t - 6.0 * t * t + 4.0) / 6.0,
            (-3.0 * t * t * t + 3.0 * t * t + 3.0 * t + 1.0) / 6.0,
            t * t * t / 6.0,
        ],
    )
}

#[cfg(test)]
mod tests;
