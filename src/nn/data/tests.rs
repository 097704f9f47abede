//! Unit tests of `crate::nn::data`.

use super::*;

#[test]
fn split_is_a_partition() {
    let (a, b) = split_indices(100, 0.3, 7);
    assert_eq!(b.len(), 30);
    let mut all: Vec<usize> = a.iter().chain(b.iter()).copied().collect();
    all.sort();
    assert_eq!(all, (0..100).collect::<Vec<_>>());
    assert_eq!(split_indices(100, 0.3, 7), (a, b));
}

#[test]
fn gather_copies_rows() {
    let x = [0.0, 1.0, 10.0, 11.0, 20.0, 21.0];
    assert_eq!(gather_rows(&x, 2, &[2, 0]), vec![20.0, 21.0, 0.0, 1.0]);
}
