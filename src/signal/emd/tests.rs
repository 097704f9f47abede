//! Unit tests of `crate::signal::emd`.

use super::*;

#[test]
fn imfs_plus_residue_is_the_signal() {
    let x: Vec<f64> = (0..700)
        .map(|k| {
            let t = k as f64;
            (t / 9.0).sin() + 0.6 * (t / 60.0).sin() + 0.001 * t
        })
        .collect();
    let r = emd(&x, &EmdParams::default()).unwrap();
    assert!(r.imfs.len() >= 2);
    for i in 0..x.len() {
        let s: f64 = r.imfs.iter().map(|m| m[i]).sum::<f64>() + r.residue[i];
        assert!((s - x[i]).abs() < 1e-12);
    }
    // The first IMF is the fast tone (interior, away from the ends).
    let err: f64 = (100..600)
        .map(|k| (r.imfs[0][k] - (k as f64 / 9.0).sin()).abs())
        .fold(0.0, f64::max);
    assert!(err < 0.1, "{err}");
}

#[test]
fn monotonic_signal_is_all_residue() {
    let x: Vec<f64> = (0..50).map(|k| (k as f64).sqrt()).collect();
    let r = emd(&x, &EmdParams::default()).unwrap();
    assert!(r.imfs.is_empty());
    assert_eq!(r.residue, x);
}

#[test]
fn extrema_handle_plateaus() {
    let (mx, mn) = extrema(&[0.0, 1.0, 1.0, 1.0, 0.0, -1.0, 0.0]);
    assert_eq!(mx, vec![(2.0, 1.0)]);
    assert_eq!(mn, vec![(5.0, -1.0)]);
}
