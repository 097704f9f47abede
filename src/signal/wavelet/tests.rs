//! Tests of the wavelet filters, transforms and thresholding.

use super::*;

#[test]
fn perfect_reconstruction_all_families() {
    let x: Vec<f64> = (0..301)
        .map(|k| (0.07 * k as f64).sin() + 0.01 * k as f64)
        .collect();
    for name in ["haar", "db2", "db5", "db10", "sym2", "sym5", "sym10"] {
        let w = Wavelet::new(name).unwrap();
        let lev = max_level(x.len(), w.len());
        let c = wavedec(&x, &w, lev);
        let y = waverec(&c, &w);
        let err = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-10, "{name}: {err}");
    }
}

#[test]
fn filters_are_orthonormal() {
    for p in 1..=10 {
        for fam in ["db", "sym"] {
            if fam == "sym" && p < 2 {
                continue;
            }
            let w = Wavelet::new(&format!("{fam}{p}")).unwrap();
            let h = &w.rec_lo;
            for s in 0..p {
                let dot: f64 = (0..h.len() - 2 * s).map(|k| h[k] * h[k + 2 * s]).sum();
                let want = if s == 0 { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-12, "{fam}{p} shift {s}: {dot}");
            }
        }
    }
}

#[test]
fn unknown_wavelet_is_an_error() {
    assert!(Wavelet::new("coif3").is_err());
    assert!(Wavelet::new("db11").is_err());
    assert!(Wavelet::new("sym1").is_err());
}

#[test]
fn soft_threshold_shrinks() {
    assert_eq!(soft_threshold(3.0, 1.0), 2.0);
    assert_eq!(soft_threshold(-3.0, 1.0), -2.0);
    assert_eq!(soft_threshold(0.5, 1.0), 0.0);
}
