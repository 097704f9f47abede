//! Training and fine-tuning the step-error network on exactly labelled segments.
//!
//! The labels come from the exact geometric route (`geometry`), the network and its training
//! from `nn`; this file only holds the recipe: features, splits (the paper's 70/30 held-out
//! test part, a validation part for early stopping), and the report.

use serde_json::{Value, json};

use super::error::{Error, Result};
use super::model::{META_VERSION, MODEL_KIND, ModelMeta};
use crate::geometry::{self, StepError, StepErrorSegment, StepErrorSolver, StepFeatures};
use crate::nn::{self, Activation, Init, Mlp, Regressor, TrainConfig, gather_rows, split_indices};

/// The training work, off the async runtime (the server's job and `truecut step train`).
pub struct TrainJob {
    /// Tool radius of the samples, mm.
    pub r: f64,
    /// Network inputs and outputs (ignored when fine-tuning: the base's are used).
    pub features: StepFeatures,
    /// Hidden layer sizes (ignored when fine-tuning).
    pub hidden: Vec<usize>,
    /// Weight initialisation.
    pub init: Init,
    /// Training hyper-parameters.
    pub cfg: TrainConfig,
    /// Held-out part for the reported test errors (0.3 = Zhang et al. 2023's 70/30).
    pub test_fraction: f64,
    /// Model to fine-tune, if any.
    pub base: Option<Regressor>,
    /// How to name the base in the report.
    pub base_name: Option<Value>,
}

/// (max, mean) absolute error, µm.
fn abs_errors(pred: &[f64], truth: &[f64]) -> (f64, f64) {
    let e = pred.iter().zip(truth).map(|(p, t)| (p - t).abs());
    let (mut max, mut sum) = (0.0f64, 0.0);
    for v in e {
        max = max.max(v);
        sum += v;
    }
    (max, sum / truth.len().max(1) as f64)
}

impl TrainJob {
    /// A fresh network with the default inputs, hidden [28, 20], He init and
    /// [`TrainConfig::default`].
    ///
    /// The default inputs are the distance profile ([`StepFeatures::profile`]): the m
    /// distances eq. 1 extremises, divided by their largest magnitude, with the network
    /// predicting what the m samples miss between them in the same unit. Coordinates (even in
    /// the segment's local frame) carry the training surface's step lengths, tool radius and
    /// heights in millimetres, and a network fed them extrapolates on any other surface
    /// (measured on 24 generated surfaces, `truecut step transfer`: see BENCHMARKS.md); the
    /// profile is the same on every smooth surface once divided by its size, so it transfers.
    pub fn new(tool_radius_mm: f64) -> Self {
        TrainJob {
            r: tool_radius_mm,
            features: StepFeatures::profile(),
            hidden: vec![28, 20],
            init: Init::He,
            cfg: TrainConfig::default(),
            test_fraction: 0.3,
            base: None,
            base_name: None,
        }
    }

    /// Labels `segs` exactly, trains (or fine-tunes the base), and returns the model (metadata
    /// filled) and the report JSON; `progress` receives 0..1 and answers whether to go on
    /// (false stops the training after the current epoch with [`Error::Cancelled`]).
    pub fn run(
        self,
        segs: &[StepErrorSegment],
        progress: &dyn Fn(f64) -> bool,
    ) -> Result<(Regressor, Value)> {
        let f = match &self.base {
            Some(b) => ModelMeta::of(b)?.features,
            None => self.features,
        };
        f.validate()?;
        let mut solver = StepErrorSolver::default().both_branches(f.n_outputs() == 2);
        let exact: Vec<StepError> = segs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                if i % 4096 == 0 {
                    crate::numeric::stop::check();
                }
                solver
                    .solve(self.r, s.cl, &s.cc)
                    .map_err(|e| geometry::Error::InSegment {
                        index: i,
                        source: Box::new(e),
                    })
            })
            .collect::<std::result::Result<_, _>>()?;
        if !progress(0.05) {
            return Err(Error::Cancelled);
        }
        let (x, info) = f.matrix(self.r, segs.iter().map(|s| (s.cl, &s.cc[..])))?;
        let t: Vec<f64> = exact
            .iter()
            .zip(&info)
            .flat_map(|(e, i)| f.targets(e, i))
            .collect();
        let y_um: Vec<f64> = exact.iter().map(|e| e.error_mm * 1000.0).collect();
        let (w, no) = (f.len(), f.n_outputs());
        let (train_idx, test_idx) = split_indices(segs.len(), self.test_fraction, self.cfg.seed);
        let (fit_pos, val_pos) = split_indices(
            train_idx.len(),
            if self.base.is_some() { 0.2 } else { 0.1 },
            self.cfg.seed + 1,
        );
        let pick = |pos: &[usize]| pos.iter().map(|&i| train_idx[i]).collect::<Vec<_>>();
        let (fit, val) = (pick(&fit_pos), pick(&val_pos));
        if fit.is_empty() || val.is_empty() {
            return Err(Error::TooFewToSplit);
        }
        let (xf, tf) = (gather_rows(&x, w, &fit), gather_rows(&t, no, &fit));
        let (xv, tv) = (gather_rows(&x, w, &val), gather_rows(&t, no, &val));
        let epochs = self.cfg.epochs as f64;
        let mut on_epoch = |s: &nn::EpochStats| progress(0.05 + 0.9 * s.epoch as f64 / epochs);
        let eval = |reg: &Regressor| -> Result<Option<(f64, f64)>> {
            if test_idx.is_empty() {
                return Ok(None);
            }
            let p = reg.predict(&gather_rows(&x, w, &test_idx))?;
            let c: Vec<_> = test_idx.iter().map(|&i| info[i]).collect();
            let truth: Vec<f64> = test_idx.iter().map(|&i| y_um[i]).collect();
            Ok(Some(abs_errors(&f.combine(&p, &c), &truth)))
        };
        let (reg, report, base_test) = match self.base {
            Some(mut reg) => {
                let before = eval(&reg)?;
                let rep = reg.fine_tune(&xf, &tf, Some((&xv, &tv)), &self.cfg, &mut on_epoch)?;
                (reg, rep, before)
            }
            None => {
                let mut sizes = vec![w];
                sizes.extend(&self.hidden);
                sizes.push(no);
                let mlp = Mlp::new(
                    &sizes,
                    Activation::Relu,
                    Activation::Identity,
                    self.init,
                    self.cfg.seed,
                )?;
                let (reg, rep) =
                    Regressor::fit(mlp, &xf, &tf, Some((&xv, &tv)), &self.cfg, &mut on_epoch)?;
                (reg, rep, None)
            }
        };
        if report.cancelled {
            return Err(Error::Cancelled);
        }
        let test = eval(&reg)?;
        let result = json!({
            "kind": MODEL_KIND,
            "samples": segs.len(),
            "train": fit.len(),
            "validation": val.len(),
            "test": test_idx.len(),
            "epochs_run": report.train_loss.len(),
            "best_epoch": report.best_epoch,
            "stopped_early": report.stopped_early,
            "best_validation_mse": report.best_val_loss,
            "test_max_abs_um": test.map(|t| t.0),
            "test_mean_abs_um": test.map(|t| t.1),
            "base": self.base_name,
            "base_test_max_abs_um": base_test.map(|t| t.0),
            "base_test_mean_abs_um": base_test.map(|t| t.1),
            "label_max_um": y_um.iter().cloned().fold(0.0, f64::max),
        });
        let meta = ModelMeta {
            kind: MODEL_KIND.into(),
            version: META_VERSION,
            features: f,
            tool_radius_mm: self.r,
            hidden: reg.mlp().sizes()[1..reg.mlp().sizes().len() - 1].to_vec(),
            output_unit: "um".into(),
            report: result.clone(),
        };
        let mut reg = reg;
        reg.metadata = serde_json::to_string(&meta).map_err(|e| Error::Metadata(e.to_string()))?;
        if !progress(0.97) {
            return Err(Error::Cancelled);
        }
        Ok((reg, result))
    }
}
