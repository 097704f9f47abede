//! Tests of the map fit: the automatic choice, cross-validation folds, accuracy against
//! the controller's table and the truth, prediction and the stored form.

use super::cv::{choose, length};
use super::*;
use crate::volumetric::{
    Error, Model, ModelKind, NetworkOptions, ResidualKind, ShapeFamily, SyntheticMachine,
};

fn score(model: ModelKind, rms_um: f64, params: usize) -> ModelScore {
    ModelScore {
        model,
        cv_rms_mm: Some(rms_um * 1e-3),
        cv_max_mm: None,
        parameter_count: Some(params),
        skipped: None,
    }
}

#[test]
fn auto_prefers_the_kinematic_model_only_within_the_tie_band() {
    use ModelKind::*;
    // a 1.6 % CV lead of the network is a tie: the rigid-body model is kept
    let tie = [
        score(Trilinear, 2.56, 557),
        score(Network, 2.42, 71),
        score(Kinematic, 2.46, 79),
    ];
    assert_eq!(choose(&tie), Some(Kinematic));
    // a clear lead wins whatever it stores
    let clear = [score(Kinematic, 1.06, 79), score(Hybrid, 0.66, 518)];
    assert_eq!(choose(&clear), Some(Hybrid));
    // a tie without the kinematic model: fewest numbers
    let other = [
        score(Kinematic, 3.0, 51),
        score(Trilinear, 2.0, 155),
        score(Network, 2.03, 71),
    ];
    assert_eq!(choose(&other), Some(Network));
    assert_eq!(choose(&[]), None);
}

fn off_grid_rms(map: &VolumetricMap, m: &SyntheticMachine) -> f64 {
    let pts = m.random_points(1500, 77);
    let pred = map.predict(&pts).unwrap();
    assert!(pred.out_of_box.iter().all(|o| !o));
    let se: f64 = pts
        .iter()
        .zip(&pred.errors)
        .map(|(&p, e)| length(*e, m.error(p)).powi(2))
        .sum();
    (se / pts.len() as f64).sqrt()
}

fn quick(model: ModelKind, m: &SyntheticMachine) -> FitOptions {
    let network = NetworkOptions {
        epochs: Some(150),
        ..NetworkOptions::default()
    };
    FitOptions {
        model,
        tool_offset_mm: m.tool_offset_mm,
        network,
        ..FitOptions::default()
    }
}

#[test]
fn auto_beats_the_controller_table_on_a_rigid_machine() {
    // issue 7's goal is ≤ 0.5× trilinear; the bench reports it over 6 machines (mean
    // ≈ 0.5, single machines up to ≈ 0.6 on the coarse grid); this test guards
    // against regressions on two machines, not the goal itself
    for (grid, seed) in [([7, 6, 5], 21), ([4, 4, 3], 22)] {
        let m = SyntheticMachine::new(seed, ShapeFamily::TrendAndWaviness);
        let d = m.measure_grid(grid, seed);
        let auto = fit(&d, &quick(ModelKind::Auto, &m)).unwrap();
        let tri = fit(&d, &quick(ModelKind::Trilinear, &m)).unwrap();
        assert_eq!(auto.scores.len(), 4);
        assert_eq!(auto.model.kind(), ModelKind::Kinematic, "{:?}", auto.scores);
        let (a, t) = (off_grid_rms(&auto, &m), off_grid_rms(&tri, &m));
        assert!(a < 0.7 * t, "{grid:?}: auto {a} vs trilinear {t}");
        assert!(auto.model.parameter_count() < tri.model.parameter_count());
        // cross-validation ranks the same way the truth does
        let cv = |k: ModelKind| {
            auto.scores
                .iter()
                .find(|s| s.model == k)
                .unwrap()
                .cv_rms_mm
                .unwrap()
        };
        assert!(cv(ModelKind::Kinematic) < cv(ModelKind::Trilinear));
    }
}

#[test]
fn hybrid_learns_what_a_rigid_model_cannot() {
    let mut m = SyntheticMachine::new(1, ShapeFamily::TrendAndWaviness);
    m.sag_mm = 8e-3;
    let d = m.measure_grid([7, 6, 5], 3);
    let kin = fit(
        &d,
        &FitOptions {
            model: ModelKind::Kinematic,
            tool_offset_mm: m.tool_offset_mm,
            max_folds: 2,
            ..FitOptions::default()
        },
    )
    .unwrap();
    let k = off_grid_rms(&kin, &m);
    // the spline (default) must do better than the network on a smooth sag
    let mut rms = vec![];
    for residual in [ResidualKind::Spline, ResidualKind::Network] {
        let o = FitOptions {
            model: ModelKind::Hybrid,
            residual,
            ..kin.options.clone()
        };
        let hybrid = fit(&d, &o).unwrap();
        let h = off_grid_rms(&hybrid, &m);
        assert!(h < 0.85 * k, "hybrid ({residual:?}) {h} vs kinematic {k}");
        assert_eq!(hybrid.scores.len(), 1);
        let Model::Hybrid(model) = &hybrid.model else {
            panic!("not a hybrid")
        };
        assert_eq!(model.residual_kind(), residual);
        // the stored form round-trips with its residual part
        let back = VolumetricMap::from_bytes(&hybrid.to_bytes()).unwrap();
        let pts = m.random_points(50, 9);
        let (a, b) = (back.model.eval_many(&pts), hybrid.model.eval_many(&pts));
        for (a, b) in a.iter().zip(&b) {
            assert!((0..3).all(|j| (a[j] - b[j]).abs() < 1e-12), "{a:?} {b:?}");
        }
        rms.push(h);
    }
    assert!(rms[0] < rms[1], "spline {} vs network {}", rms[0], rms[1]);
    // a stored hybrid without a residual part is refused, not evaluated as rigid
    let hybrid = fit(
        &d,
        &FitOptions {
            model: ModelKind::Hybrid,
            ..kin.options.clone()
        },
    )
    .unwrap();
    let mut v: serde_json::Value = serde_json::from_slice(&hybrid.to_bytes()).unwrap();
    let removed = v["model"].as_object_mut().and_then(|o| o.remove("spline"));
    assert!(removed.is_some(), "layout changed: {}", v["model"]);
    let err = VolumetricMap::from_bytes(&serde_json::to_vec(&v).unwrap()).unwrap_err();
    assert!(
        err.to_string().contains("exactly one residual part"),
        "{err}"
    );
}

#[test]
fn plane_folds_hold_out_whole_interior_planes() {
    let m = SyntheticMachine::new(3, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([4, 4, 3], 1);
    let (scheme, sets) = folds(&d, 8, 0);
    assert!(
        scheme.starts_with("leave-one-interior-plane-out"),
        "{scheme}"
    );
    assert_eq!(sets.len(), 2 + 2 + 1);
    assert_eq!(
        sets.iter().map(Vec::len).collect::<Vec<_>>(),
        vec![12, 12, 12, 12, 16]
    );
    for set in &sets {
        let rest: Vec<usize> = (0..d.nodes.len()).filter(|i| !set.contains(i)).collect();
        assert!(d.subset(&rest).grid().is_ok());
    }
    let (_, capped) = folds(&m.measure_grid([7, 6, 5], 1), 3, 0);
    assert_eq!(capped.len(), 3);
}

#[test]
fn scattered_nodes_skip_trilinear_and_reject_it_when_asked() {
    let m = SyntheticMachine::new(4, ShapeFamily::TrendAndWaviness);
    let d = m.measure(m.random_points(120, 5), 6);
    let o = quick(ModelKind::Auto, &m);
    let map = fit(
        &d,
        &FitOptions {
            max_folds: 5,
            ..o.clone()
        },
    )
    .unwrap();
    assert!(map.cv_scheme.contains("random"));
    let tri = map
        .scores
        .iter()
        .find(|s| s.model == ModelKind::Trilinear)
        .unwrap();
    assert!(
        tri.cv_rms_mm.is_none()
            && tri
                .skipped
                .as_deref()
                .unwrap()
                .contains("not a full rectilinear grid")
    );
    assert!(matches!(
        fit(
            &d,
            &FitOptions {
                model: ModelKind::Trilinear,
                ..o
            }
        ),
        Err(Error::NotAGrid { .. })
    ));
}

#[test]
fn predictions_flag_outside_points_and_the_map_round_trips() {
    let m = SyntheticMachine::new(6, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([4, 4, 3], 1);
    let map = fit(&d, &quick(ModelKind::Kinematic, &m)).unwrap();
    let p = map
        .predict(&[[100.0, 100.0, 100.0], [900.0, 100.0, 100.0]])
        .unwrap();
    assert_eq!(p.out_of_box, vec![false, true]);
    assert_eq!(p.errors[1], map.error_at([800.0, 100.0, 100.0]));
    assert_eq!(
        map.predict(&[[0.0, f64::NAN, 0.0]]),
        Err(Error::NonFinite {
            field: "points",
            index: 0
        })
    );
    let back = VolumetricMap::from_bytes(&map.to_bytes()).unwrap();
    assert_eq!(
        back.error_at([10.0, 20.0, 30.0]),
        map.error_at([10.0, 20.0, 30.0])
    );
    let mut v: serde_json::Value = serde_json::from_slice(&map.to_bytes()).unwrap();
    v["version"] = 99.into();
    assert!(matches!(
        VolumetricMap::from_bytes(&serde_json::to_vec(&v).unwrap()),
        Err(Error::ModelFormat(_))
    ));
    let n = [0.0, 0.6, 0.8];
    let e = map.error_at([5.0, 6.0, 7.0]);
    let dev = normal_deviation(&map, &[[5.0, 6.0, 7.0]], &[n]);
    assert!((dev[0] - (e[1] * 0.6 + e[2] * 0.8)).abs() < 1e-15);
}

#[test]
fn version_1_maps_are_read_as_legendre_series() {
    use crate::volumetric::MotionBasis;
    let m = SyntheticMachine::new(2, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([7, 6, 5], 1);
    let map = fit(&d, &quick(ModelKind::Kinematic, &m)).unwrap();
    let Model::Kinematic(k) = &map.model else {
        panic!("asked for kinematic")
    };
    assert_eq!(k.basis, MotionBasis::Spline);
    // the same coefficients read as a Legendre series: what a version-1 file meant
    let mut old = map.clone();
    if let Model::Kinematic(k) = &mut old.model {
        k.basis = MotionBasis::Legendre;
    }
    if let Some(c) = old.components.as_mut() {
        c.basis = MotionBasis::Legendre;
    }
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(o) => {
                o.remove("basis");
                o.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_slice(&old.to_bytes()).unwrap();
    strip(&mut v);
    v["version"] = 1.into();
    let back = VolumetricMap::from_bytes(&serde_json::to_vec(&v).unwrap()).unwrap();
    let q = [123.0, 234.0, 345.0];
    assert_eq!(back.error_at(q), old.error_at(q));
    assert_ne!(back.error_at(q), map.error_at(q));
}

#[test]
fn rejects_bad_options_and_data() {
    let m = SyntheticMachine::new(6, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([4, 4, 3], 1);
    let o = quick(ModelKind::Kinematic, &m);
    assert!(
        fit(
            &d,
            &FitOptions {
                degree: 0,
                ..o.clone()
            }
        )
        .is_err()
    );
    assert!(
        fit(
            &d,
            &FitOptions {
                tool_offset_mm: [0.0, f64::INFINITY, 0.0],
                ..o.clone()
            }
        )
        .is_err()
    );
    assert!(matches!(
        fit(&d.subset(&[0, 1, 2]), &o),
        Err(Error::TooFewNodes { .. })
    ));
}

/// Issue 25 (same input, same bits): the automatic fit (every model kind cross-validated, the
/// two network kinds on a second thread) of the same data, run twice alone and twice at once
/// on two threads, stores the same bytes each time: the scores, the chosen model and every
/// parameter.
#[test]
fn the_same_data_fits_the_same_bits_alone_or_concurrently() {
    let m = SyntheticMachine::new(22, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([4, 4, 3], 22);
    let o = quick(ModelKind::Auto, &m);
    let first = fit(&d, &o).unwrap().to_bytes();
    let second = fit(&d, &o).unwrap().to_bytes();
    assert!(first == second, "two runs alone differ");
    let (a, b) = std::thread::scope(|s| {
        let other = s.spawn(|| fit(&d, &o).unwrap().to_bytes());
        let here = fit(&d, &o).unwrap().to_bytes();
        (other.join().unwrap(), here)
    });
    assert!(a == first && b == first, "a run beside another differs");
}
