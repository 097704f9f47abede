//! Unit tests of `crate::nn::regressor`.

use super::super::{Init, Optimizer};
use super::*;

fn data() -> (Vec<f64>, Vec<f64>) {
    let x: Vec<f64> = (0..400)
        .flat_map(|i| [100.0 + (i % 20) as f64, 0.001 * (i / 20) as f64])
        .collect();
    let y: Vec<f64> = x
        .chunks(2)
        .map(|p| 5.0 * (p[0] - 110.0) / 10.0 + 2000.0 * p[1])
        .collect();
    (x, y)
}

#[test]
fn fits_in_physical_units_and_round_trips_bytes() {
    let (x, y) = data();
    let mlp = Mlp::new(
        &[2, 8, 1],
        Activation::Relu,
        Activation::Identity,
        Init::He,
        2,
    )
    .unwrap();
    let cfg = TrainConfig {
        epochs: 200,
        batch_size: 16,
        optimizer: Optimizer::adam(3e-3),
        ..TrainConfig::default()
    };
    let (mut reg, _) = Regressor::fit(mlp, &x, &y, None, &cfg, &mut |_| true).unwrap();
    let mse = reg.mse(&x, &y).unwrap();
    assert!(mse < 0.05 * 0.05 * 100.0, "mse {mse}");
    // the f32 kernel == explicit f64 scaling around the f64 network, to f32 precision
    let mut xs = reg.x_scaler().transform(&x);
    let p_explicit = {
        let mut p = reg.mlp().predict(&xs).unwrap();
        reg.y_scaler().inverse_in_place(&mut p);
        p
    };
    let p = reg.predict(&x).unwrap();
    for (a, b) in p.iter().zip(&p_explicit) {
        assert!((a - b).abs() < 1e-5 * (1.0 + b.abs()), "{a} vs {b}");
    }
    reg.metadata = "{\"m\":20}".into();
    let bytes = reg.to_bytes();
    let back = Regressor::from_bytes(&bytes).unwrap();
    assert_eq!(back, reg);
    assert_eq!(back.predict(&x).unwrap(), p);
    xs.truncate(0);
    // sigmoid output: scaler applied after the network
    let m2 = Mlp::new(
        &[2, 3, 1],
        Activation::Sigmoid,
        Activation::Sigmoid,
        Init::Xavier,
        1,
    )
    .unwrap();
    let r2 = Regressor::new(
        m2,
        ZScore::fit(&x, 2).unwrap(),
        ZScore {
            mean: vec![1.0],
            std: vec![2.0],
        },
    )
    .unwrap();
    let raw = r2.mlp().predict(&r2.x_scaler().transform(&x[..2])).unwrap();
    assert!((r2.predict(&x[..2]).unwrap()[0] - (raw[0] * 2.0 + 1.0)).abs() < 1e-6);
}

/// The f32 inference path against the f64 network on the study's data: the 615 test
/// vectors' raw coordinates (cl points and 20 cc points, mm: large means, small spreads,
/// the hard case for single precision), the [66, 28, 20, 2] step-error shape with He
/// weights and the labels' scaler (R - Lmin, Lmax - R in µm). Bound: 1e-4 µm.
#[test]
fn f32_path_matches_f64_on_study_data() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/step/");
    let main = std::fs::read_to_string(format!("{dir}testvectors.csv")).expect("vectors");
    let pm = std::fs::read_to_string(format!("{dir}testvectors_pm.csv")).expect("vectors");
    let mut cc: std::collections::HashMap<String, Vec<f64>> = Default::default();
    for line in pm.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let v = cc.entry(f[..3].join(",")).or_default();
        v.extend(f[4..7].iter().map(|v| v.parse::<f64>().unwrap()));
    }
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for line in main.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let n: Vec<f64> = f.iter().map(|v| v.parse().unwrap()).collect();
        x.extend_from_slice(&n[15..21]);
        x.extend_from_slice(&cc[&f[..3].join(",")]);
        y.extend([(5.0 - n[23]) * 1000.0, (n[24] - 5.0) * 1000.0]);
    }
    assert_eq!(x.len(), 615 * 66);
    for seed in 0..3 {
        let mlp = Mlp::new(
            &[66, 28, 20, 2],
            Activation::Relu,
            Activation::Identity,
            Init::He,
            seed,
        )
        .unwrap();
        let reg = Regressor::new(
            mlp,
            ZScore::fit(&x, 66).unwrap(),
            ZScore::fit(&y, 2).unwrap(),
        )
        .unwrap();
        let mut f64_path = reg.mlp().predict(&reg.x_scaler().transform(&x)).unwrap();
        reg.y_scaler().inverse_in_place(&mut f64_path);
        let f32_path = reg.predict(&x).unwrap();
        let parallel = reg.predict_parallel(&x, 2).unwrap();
        assert_eq!(f32_path, parallel);
        let worst = f32_path
            .iter()
            .zip(&f64_path)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let spread = f64_path.iter().map(|v| v.abs()).fold(0.0, f64::max);
        eprintln!("seed {seed}: max |f32 - f64| {worst:.2e} um (outputs up to {spread:.1} um)");
        assert!(worst < 1e-4, "max |f32 - f64| = {worst} um");
        assert!(
            spread > 1.0,
            "a network whose outputs are all ~0 tests nothing"
        );
    }
    let mut bad = x[..66 * 3].to_vec();
    bad[70] = f64::NAN;
    let reg = Regressor::new(
        Mlp::new(
            &[66, 4, 2],
            Activation::Relu,
            Activation::Identity,
            Init::He,
            0,
        )
        .unwrap(),
        ZScore::identity(66),
        ZScore::identity(2),
    )
    .unwrap();
    assert_eq!(
        reg.predict(&bad).unwrap_err(),
        Error::NonFinite {
            field: "network input",
            index: 70
        }
    );
    assert!(reg.predict(&bad[..65]).is_err());
}

#[test]
fn rejects_mismatched_scalers() {
    let mlp = Mlp::new(
        &[2, 3, 1],
        Activation::Relu,
        Activation::Identity,
        Init::He,
        0,
    )
    .unwrap();
    assert!(Regressor::new(mlp, ZScore::identity(3), ZScore::identity(1)).is_err());
}
