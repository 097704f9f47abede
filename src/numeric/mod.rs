//! The numeric toolbox every core may use: one of each building block, so that a fix or a
//! speed-up lands everywhere at once. It imports no other module of the crate.
//!
//! - [`brent`]: 1-D minimisation on a bracket (Brent 1973), plain or after a grid scan.
//! - [`tridiag`]: tridiagonal solve (Thomas algorithm) for the cubic splines.
//! - [`bspline`]: the uniform cubic B-spline basis.
//! - [`penalty`]: difference penalties `DᵀD` of P-splines and Whittaker smoothers.
//! - [`lsq`]: least squares that drop unidentifiable columns, under two named rank policies.
//! - [`vec3`]: 3-vector helpers on `[f64; 3]`.
//! - [`parallel`]: thread counts and the ways the cores split work over scoped threads.
//! - [`stop`]: the should-stop check long work polls, so a cancelled job frees its worker.

pub mod brent;
pub mod bspline;
pub mod lsq;
pub mod parallel;
pub mod penalty;
pub mod stop;
pub mod tridiag;
pub mod vec3;
