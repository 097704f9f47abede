//! The network of Zhang et al. 2023 on the study's surfaces, at test scale (the full experiment
//! with all 19,800 segments per surface and 0/1/5/10/15 % fine-tuning is
//! `cargo bench --bench step_error`).

use truecut::geometry::{
    HeightSurface, PathPlan, RowInfo, StepError, StepErrorSegment, StepErrorSolver, StepFeatures,
    height_surface_segments,
};
use truecut::nn::{Activation, Init, Mlp, Regressor, TrainConfig, gather_rows, split_indices};

const R: f64 = 5.0;

struct Data {
    segs: Vec<StepErrorSegment>,
    exact: Vec<StepError>,
    y_um: Vec<f64>,
}

/// Surface `id` with `lines` x `pts` CL points (the study: 200 x 100), labelled exactly.
fn data(id: u32, lines: usize, pts: usize) -> Data {
    let s = HeightSurface::reference(id).unwrap();
    let plan = PathPlan {
        lines: Some(lines),
        points_per_line: Some(pts),
        ..PathPlan::study()
    };
    let segs = height_surface_segments(&s, &plan).unwrap();
    let mut solver = StepErrorSolver::default().both_branches(true);
    let exact: Vec<StepError> = segs
        .iter()
        .map(|g| solver.solve(R, g.cl, &g.cc).unwrap())
        .collect();
    let y_um = exact.iter().map(|e| e.error_mm * 1000.0).collect();
    Data { segs, exact, y_um }
}

fn xy(f: &StepFeatures, d: &Data) -> (Vec<f64>, Vec<RowInfo>, Vec<f64>) {
    let (x, c) = f
        .matrix(R, d.segs.iter().map(|s| (s.cl, &s.cc[..])))
        .unwrap();
    let t = d
        .exact
        .iter()
        .zip(&c)
        .flat_map(|(e, i)| f.targets(e, i))
        .collect();
    (x, c, t)
}

/// (max, mean) absolute error in µm.
fn abs_err(pred: &[f64], truth: &[f64]) -> (f64, f64) {
    let e: Vec<f64> = pred.iter().zip(truth).map(|(p, t)| (p - t).abs()).collect();
    (
        e.iter().cloned().fold(0.0, f64::max),
        e.iter().sum::<f64>() / e.len() as f64,
    )
}

/// Trains on surface 1 (70 % of it, 10 % of that for early stopping) and returns the model and
/// the (max, mean) error on the other 30 %.
fn train_surface1(
    f: &StepFeatures,
    d: &Data,
    init: Init,
    cfg: &TrainConfig,
) -> (Regressor, (f64, f64)) {
    let (x, c, t) = xy(f, d);
    let (w, no) = (f.len(), f.n_outputs());
    let (train, test) = split_indices(d.y_um.len(), 0.3, 0);
    let (fit, val) = split_indices(train.len(), 0.1, 1);
    let fit: Vec<usize> = fit.iter().map(|&i| train[i]).collect();
    let val: Vec<usize> = val.iter().map(|&i| train[i]).collect();
    let mlp = Mlp::new(
        &[w, 28, 20, no],
        Activation::Relu,
        Activation::Identity,
        init,
        0,
    )
    .unwrap();
    let (reg, _) = Regressor::fit(
        mlp,
        &gather_rows(&x, w, &fit),
        &gather_rows(&t, no, &fit),
        Some((&gather_rows(&x, w, &val), &gather_rows(&t, no, &val))),
        cfg,
        &mut |_| true,
    )
    .unwrap();
    let pred = f.combine(
        &reg.predict(&gather_rows(&x, w, &test)).unwrap(),
        &test.iter().map(|&i| c[i]).collect::<Vec<_>>(),
    );
    let truth: Vec<f64> = test.iter().map(|&i| d.y_um[i]).collect();
    (reg, abs_err(&pred, &truth))
}

/// Zhang et al. 2023's settings (N(0,1) weights, SGD lr 1e-5 momentum 0.8, dropout 0.5, global
/// inputs) stay near "predict the mean" while the default reaches sub-0.2 µm with the same epochs.
/// Zhang et al. 2023: MSE 0.001 after 2000 epochs, test max 0.78 µm (its Fig. 5, Table 3).
#[test]
fn paper_settings_do_not_converge_but_the_default_does() {
    let d = data(1, 100, 100);
    let epochs = 40;
    let paper = TrainConfig {
        epochs,
        ..TrainConfig::paper()
    };
    let (_, (pmax, pmean)) =
        train_surface1(&StepFeatures::paper(), &d, Init::StandardNormal, &paper);
    let default = TrainConfig {
        epochs,
        ..TrainConfig::default()
    };
    let f = StepFeatures {
        two_sided: true,
        ..StepFeatures::local()
    };
    let (_, (dmax, dmean)) = train_surface1(&f, &d, Init::He, &default);
    let mean_label = d.y_um.iter().sum::<f64>() / d.y_um.len() as f64;
    let mean_pred_err =
        d.y_um.iter().map(|y| (y - mean_label).abs()).sum::<f64>() / d.y_um.len() as f64;
    eprintln!(
        "{epochs} epochs, surface 1 test: paper settings max {pmax:.2} / mean {pmean:.3} um; default max {dmax:.3} / mean \
         {dmean:.4} um; always-the-mean {mean_pred_err:.2} um (paper after 2000 epochs: max 0.78 um)"
    );
    assert!(
        pmean > 0.5 * mean_pred_err,
        "paper settings converged: mean {pmean} um"
    );
    assert!(
        dmean < 0.1 && dmax < 1.0,
        "default did not converge: max {dmax} mean {dmean} um"
    );
}

/// Local-frame, two-sided network trained on surface 1 only predicts surfaces 2 and 3 with no
/// fine-tuning (Zhang et al. 2023 needed 15 % of each new surface: max 5.25 / 0.99 µm).
#[test]
fn local_frame_network_transfers_without_fine_tuning() {
    let d1 = data(1, 200, 100);
    let f = StepFeatures {
        two_sided: true,
        ..StepFeatures::local()
    };
    let cfg = TrainConfig::default();
    let (reg, (max1, mean1)) = train_surface1(&f, &d1, Init::He, &cfg);
    eprintln!("surface 1 test: max {max1:.3} mean {mean1:.4} um (paper 0.78 max)");
    assert!(
        max1 < 0.5 && mean1 < 0.03,
        "surface 1: max {max1} mean {mean1}"
    );
    for id in [2, 3] {
        let d = data(id, 200, 100);
        let (x, c, _) = xy(&f, &d);
        let (max, mean) = abs_err(&f.combine(&reg.predict(&x).unwrap(), &c), &d.y_um);
        eprintln!(
            "surface {id}, 0 % fine-tuning: max {max:.3} mean {mean:.4} um (goal <= 1 / 0.05; study 1.16-1.41 / 0.055-0.101)"
        );
        assert!(
            max < 1.0 && mean < 0.05,
            "surface {id}: max {max} mean {mean}"
        );
    }
}

/// Fine-tuning a base model on a few percent of a new surface never ends worse on held-out
/// samples of that surface (best-epoch restore includes the starting weights).
#[test]
fn fine_tuning_with_few_samples_does_not_degrade() {
    let d1 = data(1, 40, 60);
    let f = StepFeatures {
        two_sided: true,
        ..StepFeatures::local()
    };
    let (base, _) = train_surface1(
        &f,
        &d1,
        Init::He,
        &TrainConfig {
            epochs: 30,
            ..TrainConfig::default()
        },
    );
    let d3 = data(3, 40, 60);
    let (x, c, t) = xy(&f, &d3);
    let (w, no) = (f.len(), f.n_outputs());
    let (rest, tune) = split_indices(d3.y_um.len(), 0.05, 3);
    let (tp, vp) = split_indices(tune.len(), 0.2, 7);
    let ti: Vec<usize> = tp.iter().map(|&i| tune[i]).collect();
    let vi: Vec<usize> = vp.iter().map(|&i| tune[i]).collect();
    let mut tuned = base.clone();
    let rep = tuned
        .fine_tune(
            &gather_rows(&x, w, &ti),
            &gather_rows(&t, no, &ti),
            Some((&gather_rows(&x, w, &vi), &gather_rows(&t, no, &vi))),
            &TrainConfig {
                epochs: 40,
                patience: Some(10),
                ..TrainConfig::default()
            },
            &mut |_| true,
        )
        .unwrap();
    let xv = gather_rows(&x, w, &vi);
    let tv = gather_rows(&t, no, &vi);
    assert!(tuned.mse(&xv, &tv).unwrap() <= base.mse(&xv, &tv).unwrap() + 1e-12);
    let cr: Vec<RowInfo> = rest.iter().map(|&i| c[i]).collect();
    let yr: Vec<f64> = rest.iter().map(|&i| d3.y_um[i]).collect();
    let before = abs_err(
        &f.combine(&base.predict(&gather_rows(&x, w, &rest)).unwrap(), &cr),
        &yr,
    );
    let after = abs_err(
        &f.combine(&tuned.predict(&gather_rows(&x, w, &rest)).unwrap(), &cr),
        &yr,
    );
    eprintln!(
        "surface 3 rest, 5 % fine-tuning: mean {:.4} -> {:.4} um (best epoch {})",
        before.1, after.1, rep.best_epoch
    );
    assert!(
        after.1 <= before.1 * 1.05,
        "fine-tuning degraded: {before:?} -> {after:?}"
    );
}
