//! Unit tests of `crate::nn::train`.

use super::super::{Activation, Init};
use super::*;

/// Analytic gradient (via one SGD step with lr 1, momentum 0) equals finite differences.
#[test]
fn backprop_gradient_matches_finite_difference() {
    for act in [Activation::Relu, Activation::Sigmoid] {
        let m0 = Mlp::new(&[3, 5, 4, 2], act, Activation::Identity, Init::Xavier, 11).unwrap();
        let x: Vec<f64> = (0..8 * 3)
            .map(|i| ((i * 13 % 17) as f64) / 8.0 - 1.0)
            .collect();
        let y: Vec<f64> = (0..8 * 2)
            .map(|i| ((i * 7 % 11) as f64) / 5.0 - 1.0)
            .collect();
        let cfg = TrainConfig {
            optimizer: Optimizer::Sgd {
                lr: 1.0,
                momentum: 0.0,
            },
            schedule: LrSchedule::Constant,
            ..TrainConfig::default()
        };
        let mut m1 = m0.clone();
        let mut st = OptimizerState::new(&[15, 5, 20, 4, 8, 2]);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(0);
        step(&mut m1, &x, &y, 8, &cfg, 1.0, &mut st, &mut rng);
        for l in 0..3 {
            for k in 0..m0.layers[l].w.len() {
                let analytic = m0.layers[l].w.as_slice()[k] - m1.layers[l].w.as_slice()[k];
                let h = 1e-6;
                let mut mp = m0.clone();
                mp.layers[l].w.as_mut_slice()[k] += h;
                let mut mm = m0.clone();
                mm.layers[l].w.as_mut_slice()[k] -= h;
                let fd = (mse(&mp, &x, &y) - mse(&mm, &x, &y)) / (2.0 * h);
                assert!(
                    (fd - analytic).abs() < 1e-6,
                    "{act:?} layer {l} w{k}: fd {fd} vs {analytic}"
                );
            }
        }
    }
}

#[test]
fn learns_a_smooth_function_and_early_stops() {
    // y = sin(x0) + x1^2 on [-1, 1]^2
    let f = |a: f64, b: f64| a.sin() + b * b;
    let grid: Vec<f64> = (0..900)
        .flat_map(|i| [(i % 30) as f64 / 14.5 - 1.0, (i / 30) as f64 / 14.5 - 1.0])
        .collect();
    let y: Vec<f64> = grid.chunks(2).map(|p| f(p[0], p[1])).collect();
    let (tr, va) = super::super::split_indices(900, 0.3, 1);
    let (xt, yt) = (
        super::super::gather_rows(&grid, 2, &tr),
        super::super::gather_rows(&y, 1, &tr),
    );
    let (xv, yv) = (
        super::super::gather_rows(&grid, 2, &va),
        super::super::gather_rows(&y, 1, &va),
    );
    let mut m = Mlp::new(
        &[2, 16, 16, 1],
        Activation::Relu,
        Activation::Identity,
        Init::He,
        5,
    )
    .unwrap();
    let before = mse(&m, &xv, &yv);
    let cfg = TrainConfig {
        epochs: 150,
        batch_size: 32,
        patience: Some(10),
        ..TrainConfig::default()
    };
    let mut calls = 0;
    let rep = train(&mut m, &xt, &yt, Some((&xv, &yv)), &cfg, &mut |_| {
        calls += 1;
        true
    })
    .unwrap();
    let after = mse(&m, &xv, &yv);
    assert!(
        after < 5e-3 && after < before / 50.0,
        "val mse {before} -> {after}"
    );
    assert_eq!(rep.best_val_loss, Some(after));
    assert_eq!(calls, rep.train_loss.len());
    assert!(rep.val_loss.iter().all(|v| *v >= after));
}

#[test]
fn callback_cancels_and_bad_config_is_rejected() {
    let mut m = Mlp::new(
        &[1, 4, 1],
        Activation::Relu,
        Activation::Identity,
        Init::He,
        0,
    )
    .unwrap();
    let x = [0.0, 0.5, 1.0];
    let y = [0.0, 0.25, 1.0];
    let rep = train(&mut m, &x, &y, None, &TrainConfig::default(), &mut |s| {
        s.epoch < 3
    })
    .unwrap();
    assert!(rep.cancelled);
    assert_eq!(rep.train_loss.len(), 3);
    let bad = TrainConfig {
        dropout: 1.0,
        ..TrainConfig::default()
    };
    assert!(train(&mut m, &x, &y, None, &bad, &mut |_| true).is_err());
    assert!(
        train(
            &mut m,
            &x,
            &y[..2],
            None,
            &TrainConfig::default(),
            &mut |_| true
        )
        .is_err()
    );
}
