//! Row-major sample helpers: random splits and row gathering.

use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;
use rand::seq::SliceRandom;

/// Splits `0..n` at random into (first, second) index sets, `second` holding
/// `round(n * second_fraction)` indices (the 70/30 split of Zhang et al. 2023 is
/// `second_fraction = 0.3`). Deterministic for a given `seed`. Fractions outside [0, 1] are
/// clamped.
pub fn split_indices(n: usize, second_fraction: f64, seed: u64) -> (Vec<usize>, Vec<usize>) {
    let mut idx: Vec<usize> = (0..n).collect();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    idx.shuffle(&mut rng);
    let k = ((n as f64) * second_fraction.clamp(0.0, 1.0)).round() as usize;
    let second = idx.split_off(n - k.min(n));
    (idx, second)
}

/// Copies rows `indices` of a row-major matrix with `cols` columns into a new row-major matrix.
///
/// Panics if an index is out of range (callers pass indices from [`split_indices`]).
pub fn gather_rows(x: &[f64], cols: usize, indices: &[usize]) -> Vec<f64> {
    let mut out = Vec::with_capacity(indices.len() * cols);
    for &i in indices {
        out.extend_from_slice(&x[i * cols..(i + 1) * cols]);
    }
    out
}

#[cfg(test)]
mod tests;
