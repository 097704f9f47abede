//! The cached plans against a fresh planner's (the slow oracle): same transform, bit for
//! bit, and the cache hands back the same plan for the same length.

use super::{forward, inverse};
use realfft::RealFftPlanner;
use std::sync::Arc;

#[test]
fn cached_plans_match_fresh_ones() {
    for len in [16usize, 30, 4050, 40_000] {
        let x: Vec<f64> = (0..len)
            .map(|k| ((k * 7919) % 1000) as f64 * 1e-3 - 0.5)
            .collect();
        let mut fresh = RealFftPlanner::<f64>::new();
        let (f0, f1) = (fresh.plan_fft_forward(len), forward(len));
        let (mut a, mut b) = (x.clone(), x.clone());
        let (mut sa, mut sb) = (f0.make_output_vec(), f1.make_output_vec());
        f0.process(&mut a, &mut sa).unwrap();
        f1.process(&mut b, &mut sb).unwrap();
        assert_eq!(sa, sb, "forward {len}");
        let (i0, i1) = (fresh.plan_fft_inverse(len), inverse(len));
        let (mut ya, mut yb) = (i0.make_output_vec(), i1.make_output_vec());
        i0.process(&mut sa, &mut ya).unwrap();
        i1.process(&mut sb, &mut yb).unwrap();
        assert_eq!(ya, yb, "inverse {len}");
        assert!(Arc::ptr_eq(&forward(len), &f1), "forward {len} not cached");
    }
}

#[test]
fn tables_are_computed_once_and_shared() {
    use super::{Table, table};
    let a = table(Table::Eigenvalues(3), 1234, || vec![1.0, 2.0]);
    let b = table(Table::Eigenvalues(3), 1234, || panic!("computed again"));
    assert!(Arc::ptr_eq(&a, &b));
    let c = table(Table::Eigenvalues(4), 1234, || vec![3.0]);
    assert_eq!(*c, vec![3.0]);
}
