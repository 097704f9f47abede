//! Unit tests of `crate::nn::fast`.

use super::super::Init;
use super::*;

/// The f32 kernel (portable and, where the CPU has it, AVX2) against the f64 kernel on
/// shapes that exercise every tile width (8..32 outputs, a layer wider than one tile),
/// a partial last block, a non-ReLU activation, and the input / output affine maps.
#[test]
fn f32_kernels_match_f64() {
    for (sizes, hidden) in [
        (&[67usize, 28, 20, 2][..], Activation::Relu),
        (&[5, 40, 9, 16, 3][..], Activation::Sigmoid),
        (&[3, 8, 3][..], Activation::Sigmoid),
    ] {
        let mlp = Mlp::new(sizes, hidden, Activation::Identity, Init::He, 7).unwrap();
        let (ni, no) = (mlp.n_inputs(), mlp.n_outputs());
        let n = 101;
        let x: Vec<f64> = (0..n * ni)
            .map(|i| 100.0 + ((i * 37 % 101) as f64 / 50.0 - 1.0) * 0.01)
            .collect();
        let (mean, std) = (vec![100.0; ni], vec![0.01; ni]);
        let (scale, shift) = (vec![2.5; no], vec![-1.0; no]);
        let xs: Vec<f64> = x.iter().map(|v| (v - 100.0) / 0.01).collect();
        let mut want = vec![0.0; n * no];
        Packed::new(&mlp).forward(&xs, &mut want);
        want.iter_mut().for_each(|v| *v = *v * 2.5 - 1.0);
        let p = Packed32::new(&mlp, (&mean, &std), (&scale, &shift));
        let mut portable = vec![0.0; n * no];
        assert!(forward32::<false>(&p, &x, &mut portable));
        let mut dispatched = vec![0.0; n * no];
        assert!(p.forward(&x, &mut dispatched));
        let top = want.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        for (i, w) in want.iter().enumerate() {
            for got in [portable[i], dispatched[i]] {
                assert!(
                    (got - w).abs() < 1e-5 * top,
                    "{sizes:?} [{i}]: {got} vs {w}"
                );
            }
        }
        let mut bad = x.clone();
        bad[n * ni - 1] = f64::INFINITY;
        assert!(!p.forward(&bad, &mut dispatched));
        assert!(!forward32::<false>(&p, &bad, &mut portable));
    }
}
