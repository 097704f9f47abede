//! Unit tests of `crate::nn::mlp`.

use super::*;

fn naive(m: &Mlp, x: &[f64]) -> Vec<f64> {
    let mut a = x.to_vec();
    for l in &m.layers {
        let mut z = vec![0.0; l.w.nrows()];
        for (r, zr) in z.iter_mut().enumerate() {
            *zr = l
                .activation
                .apply((0..l.w.ncols()).map(|c| l.w[(r, c)] * a[c]).sum::<f64>() + l.b[r]);
        }
        a = z;
    }
    a
}

#[test]
fn batch_forward_matches_naive_per_sample() {
    let m = Mlp::new(
        &[7, 28, 20, 2],
        Activation::Relu,
        Activation::Identity,
        Init::StandardNormal,
        3,
    )
    .unwrap();
    let n = 600; // crosses block boundaries
    let x: Vec<f64> = (0..n * 7)
        .map(|i| ((i * 37 % 101) as f64) / 50.0 - 1.0)
        .collect();
    let y = m.predict(&x).unwrap();
    let yp = m.predict_parallel(&x, 2).unwrap();
    for i in 0..n {
        let r = naive(&m, &x[i * 7..(i + 1) * 7]);
        for k in 0..2 {
            assert!((y[i * 2 + k] - r[k]).abs() < 1e-9 * (1.0 + r[k].abs()));
            assert_eq!(y[i * 2 + k], yp[i * 2 + k]);
        }
    }
}

#[test]
fn sigmoid_3_8_3() {
    let m = Mlp::new(
        &[3, 8, 3],
        Activation::Sigmoid,
        Activation::Identity,
        Init::Xavier,
        1,
    )
    .unwrap();
    assert_eq!(m.sizes(), vec![3, 8, 3]);
    assert_eq!(m.n_parameters(), 3 * 8 + 8 + 8 * 3 + 3);
    let x = [0.1, -0.2, 0.3];
    let y = m.predict_one(&x).unwrap();
    let r = naive(&m, &x);
    for k in 0..3 {
        assert!((y[k] - r[k]).abs() < 1e-12);
    }
}

#[test]
fn rejects_bad_shapes() {
    assert_eq!(
        Mlp::new(&[3], Activation::Relu, Activation::Identity, Init::He, 0),
        Err(Error::TooFewLayers(1))
    );
    assert!(matches!(
        Mlp::new(
            &[3, 0, 1],
            Activation::Relu,
            Activation::Identity,
            Init::He,
            0
        ),
        Err(Error::EmptyLayer { index: 1 })
    ));
    let m = Mlp::new(
        &[3, 4, 1],
        Activation::Relu,
        Activation::Identity,
        Init::He,
        0,
    )
    .unwrap();
    assert!(m.predict(&[1.0, 2.0]).is_err());
    assert!(matches!(
        m.predict(&[1.0, f64::INFINITY, 0.0]),
        Err(Error::NonFinite { index: 1, .. })
    ));
}
