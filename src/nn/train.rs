//! Mini-batch back-propagation with dropout, SGD-momentum or Adam, early stopping.

use nalgebra::{DMatrix, DMatrixView};
use rand::rngs::Xoshiro256PlusPlus;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};

use super::error::{Error, Result, check_finite};
use super::mlp::Mlp;
use super::optimizer::{LrSchedule, Optimizer, OptimizerState};

/// Hyper-parameters of one training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Maximum number of passes over the training set.
    pub epochs: usize,
    /// Samples per gradient step; 0 means the full batch (batch gradient descent).
    pub batch_size: usize,
    /// Probability of dropping a hidden neuron during training, in [0, 1) (Zhang et al. 2023 eq. 13
    /// uses the keep probability p = 0.5, i.e. dropout 0.5). Inverted dropout: kept
    /// activations are scaled by 1/(1 - dropout), so inference needs no rescaling.
    pub dropout: f64,
    /// Update rule.
    pub optimizer: Optimizer,
    /// Learning-rate schedule over `epochs`.
    pub schedule: LrSchedule,
    /// Stop when the validation loss has not improved for this many epochs (needs validation
    /// data). With validation data the weights of the best epoch are restored at the end.
    pub patience: Option<usize>,
    /// Seed of shuffling and dropout masks.
    pub seed: u64,
}

impl Default for TrainConfig {
    /// What converges on the step-error data: Adam 1e-3 with cosine decay to 1e-5, batch 64,
    /// no dropout, early stopping after 40 epochs without improvement, at most 300 epochs.
    fn default() -> Self {
        TrainConfig {
            epochs: 300,
            batch_size: 64,
            dropout: 0.0,
            optimizer: Optimizer::adam(1e-3),
            schedule: LrSchedule::Cosine { final_factor: 0.01 },
            patience: Some(40),
            seed: 0,
        }
    }
}

impl TrainConfig {
    /// The paper's settings (Zhang et al. 2023, "Network parameter determination"): SGD with
    /// momentum, eta = 1e-5, beta = 0.8, dropout 0.5, 2000 epochs. The paper gives no batch
    /// size; 64 as in the Python study. Pair with [`super::Init::StandardNormal`] weights.
    /// In practice this does not converge (see the step-error tests).
    pub fn paper() -> Self {
        TrainConfig {
            epochs: 2000,
            batch_size: 64,
            dropout: 0.5,
            optimizer: Optimizer::Sgd {
                lr: 1e-5,
                momentum: 0.8,
            },
            schedule: LrSchedule::Constant,
            patience: None,
            seed: 0,
        }
    }

    fn validate(&self) -> Result<()> {
        self.optimizer.validate()?;
        if !(0.0..1.0).contains(&self.dropout) {
            return Err(Error::InvalidParameter {
                name: "dropout",
                value: self.dropout,
                reason: "must be in [0, 1)",
            });
        }
        if self.epochs == 0 {
            return Err(Error::InvalidParameter {
                name: "epochs",
                value: 0.0,
                reason: "must be >= 1",
            });
        }
        if let LrSchedule::Cosine { final_factor } = self.schedule
            && !(final_factor > 0.0 && final_factor <= 1.0)
        {
            return Err(Error::InvalidParameter {
                name: "final_factor",
                value: final_factor,
                reason: "must be in (0, 1]",
            });
        }
        Ok(())
    }
}

/// What the progress callback sees after each epoch.
#[derive(Clone, Debug, PartialEq)]
pub struct EpochStats {
    /// 1-based epoch just finished.
    pub epoch: usize,
    /// Maximum number of epochs.
    pub epochs: usize,
    /// Mean training MSE of the epoch (scaled units, with dropout active).
    pub train_loss: f64,
    /// Validation MSE (scaled units, no dropout), when validation data was given.
    pub val_loss: Option<f64>,
    /// Learning rate used in the epoch.
    pub lr: f64,
}

/// Loss history and outcome of a training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainReport {
    /// Training MSE per epoch.
    pub train_loss: Vec<f64>,
    /// Validation MSE per epoch (empty without validation data).
    pub val_loss: Vec<f64>,
    /// 1-based epoch whose weights were kept (the last one without validation data; 0 when
    /// no epoch beat the starting weights on the validation data).
    pub best_epoch: usize,
    /// Validation MSE of the kept weights.
    pub best_val_loss: Option<f64>,
    /// True when early stopping ended the run before `epochs`.
    pub stopped_early: bool,
    /// True when the callback asked to stop.
    pub cancelled: bool,
}

/// Trains `mlp` in place on row-major `x` (`n x n_inputs`) and `y` (`n x n_outputs`) with
/// mean-squared-error loss (Zhang et al. 2023 eq. 4), back-propagation (eqs. 5–6), dropout on
/// hidden layers (eq. 13) and the configured optimiser (eq. 14 for SGD-momentum).
///
/// `validation` is an optional held-out `(x, y)` for early stopping and best-epoch restore.
/// `on_epoch` is called after every epoch; returning `false` stops training (cancellation).
/// Inputs and targets should already be scaled (see [`super::ZScore`], [`super::Regressor`]).
/// Errors: shape mismatches, non-finite data, bad hyper-parameters, a non-finite loss.
pub fn train(
    mlp: &mut Mlp,
    x: &[f64],
    y: &[f64],
    validation: Option<(&[f64], &[f64])>,
    cfg: &TrainConfig,
    on_epoch: &mut dyn FnMut(&EpochStats) -> bool,
) -> Result<TrainReport> {
    cfg.validate()?;
    let (ni, no) = (mlp.n_inputs(), mlp.n_outputs());
    let n = check_xy(x, y, ni, no, "training")?;
    if n == 0 {
        return Err(Error::TooFewSamples {
            what: "training",
            min: 1,
            got: 0,
        });
    }
    if let Some((vx, vy)) = validation {
        let nv = check_xy(vx, vy, ni, no, "validation")?;
        if nv == 0 {
            return Err(Error::TooFewSamples {
                what: "validation",
                min: 1,
                got: 0,
            });
        }
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(cfg.seed);
    let sizes: Vec<usize> = mlp
        .layers
        .iter()
        .flat_map(|l| [l.w.len(), l.b.len()])
        .collect();
    let mut state = OptimizerState::new(&sizes);
    let batch = if cfg.batch_size == 0 {
        n
    } else {
        cfg.batch_size.min(n)
    };
    let mut order: Vec<usize> = (0..n).collect();
    let mut report = TrainReport {
        train_loss: Vec::new(),
        val_loss: Vec::new(),
        best_epoch: 0,
        best_val_loss: None,
        stopped_early: false,
        cancelled: false,
    };
    // With validation data the starting weights are a candidate too (epoch 0), so fine-tuning
    // a base model on few samples can never end worse on the held-out part than it started.
    let mut best: Option<(f64, Mlp)> = validation.map(|(vx, vy)| (mse(mlp, vx, vy), mlp.clone()));
    let mut since_best = 0usize;
    let mut xb = Vec::with_capacity(batch * ni);
    let mut yb = Vec::with_capacity(batch * no);
    for epoch in 0..cfg.epochs {
        let lr = cfg.optimizer.lr() * cfg.schedule.factor(epoch, cfg.epochs);
        order.shuffle(&mut rng);
        let mut loss_sum = 0.0;
        for chunk in order.chunks(batch) {
            crate::numeric::stop::check();
            xb.clear();
            yb.clear();
            for &i in chunk {
                xb.extend_from_slice(&x[i * ni..(i + 1) * ni]);
                yb.extend_from_slice(&y[i * no..(i + 1) * no]);
            }
            let loss = step(mlp, &xb, &yb, chunk.len(), cfg, lr, &mut state, &mut rng);
            loss_sum += loss * chunk.len() as f64;
        }
        let train_loss = loss_sum / n as f64;
        if !train_loss.is_finite() {
            return Err(Error::Diverged { epoch: epoch + 1 });
        }
        report.train_loss.push(train_loss);
        let val_loss = validation.map(|(vx, vy)| mse(mlp, vx, vy));
        if let Some(v) = val_loss {
            report.val_loss.push(v);
            if best.as_ref().is_none_or(|(b, _)| v < *b) {
                best = Some((v, mlp.clone()));
                report.best_epoch = epoch + 1;
                since_best = 0;
            } else {
                since_best += 1;
            }
        } else {
            report.best_epoch = epoch + 1;
        }
        let go_on = on_epoch(&EpochStats {
            epoch: epoch + 1,
            epochs: cfg.epochs,
            train_loss,
            val_loss,
            lr,
        });
        if !go_on {
            report.cancelled = true;
            break;
        }
        if let Some(p) = cfg.patience
            && validation.is_some()
            && since_best >= p
        {
            report.stopped_early = epoch + 1 < cfg.epochs;
            break;
        }
    }
    if let Some((v, m)) = best {
        *mlp = m;
        report.best_val_loss = Some(v);
    }
    Ok(report)
}

/// Mean squared error of `mlp` on row-major `x`, `y` (no dropout).
pub(crate) fn mse(mlp: &Mlp, x: &[f64], y: &[f64]) -> f64 {
    let mut out = vec![0.0; y.len()];
    mlp.forward_blocks(x, &mut out);
    out.iter()
        .zip(y)
        .map(|(p, t)| (p - t) * (p - t))
        .sum::<f64>()
        / y.len().max(1) as f64
}

fn check_xy(x: &[f64], y: &[f64], ni: usize, no: usize, what: &'static str) -> Result<usize> {
    if x.len() % ni != 0 {
        return Err(Error::Shape {
            what: "inputs (multiple of the input size)",
            expected: ni,
            got: x.len(),
        });
    }
    let n = x.len() / ni;
    if y.len() != n * no {
        return Err(Error::Shape {
            what: "targets (samples x outputs)",
            expected: n * no,
            got: y.len(),
        });
    }
    check_finite(
        if what == "training" {
            "training inputs"
        } else {
            "validation inputs"
        },
        x,
    )?;
    check_finite(
        if what == "training" {
            "training targets"
        } else {
            "validation targets"
        },
        y,
    )?;
    Ok(n)
}

/// One forward/backward pass and update on a batch of `rows` samples; returns the batch MSE.
#[allow(clippy::too_many_arguments)]
fn step(
    mlp: &mut Mlp,
    xb: &[f64],
    yb: &[f64],
    rows: usize,
    cfg: &TrainConfig,
    lr: f64,
    state: &mut OptimizerState,
    rng: &mut Xoshiro256PlusPlus,
) -> f64 {
    let nl = mlp.layers.len();
    let keep = 1.0 - cfg.dropout;
    // pre[l]: activation output of layer l; post[l]: after dropout (input of layer l+1).
    let mut pre: Vec<DMatrix<f64>> = Vec::with_capacity(nl);
    let mut masks: Vec<Option<Vec<f64>>> = Vec::with_capacity(nl);
    let mut post: Vec<DMatrix<f64>> = Vec::with_capacity(nl);
    for (l, layer) in mlp.layers.iter().enumerate() {
        let src: &[f64] = if l == 0 { xb } else { post[l - 1].as_slice() };
        let mut a = DMatrix::zeros(layer.w.nrows(), rows);
        super::mlp::dense_forward(layer, src, rows, a.as_mut_slice());
        if l + 1 < nl && cfg.dropout > 0.0 {
            let scale = 1.0 / keep;
            let mask: Vec<f64> = (0..a.len())
                .map(|_| {
                    if rng.random::<f64>() < keep {
                        scale
                    } else {
                        0.0
                    }
                })
                .collect();
            let mut p = a.clone();
            p.as_mut_slice()
                .iter_mut()
                .zip(&mask)
                .for_each(|(v, m)| *v *= m);
            pre.push(a);
            post.push(p);
            masks.push(Some(mask));
        } else {
            post.push(a.clone());
            pre.push(a);
            masks.push(None);
        }
    }
    let out = &pre[nl - 1];
    let no = out.nrows();
    let denom = (rows * no) as f64;
    let mut loss = 0.0;
    // g = dLoss/d(post of the current layer)
    let mut g = DMatrix::zeros(no, rows);
    for ((gi, o), t) in g.as_mut_slice().iter_mut().zip(out.as_slice()).zip(yb) {
        let d = o - t;
        loss += d * d;
        *gi = 2.0 * d / denom;
    }
    state.next_step();
    for l in (0..nl).rev() {
        let act = mlp.layers[l].activation;
        let mut dz = g;
        if let Some(mask) = &masks[l] {
            dz.as_mut_slice()
                .iter_mut()
                .zip(mask)
                .for_each(|(v, m)| *v *= m);
        }
        dz.as_mut_slice()
            .iter_mut()
            .zip(pre[l].as_slice())
            .for_each(|(v, a)| *v *= act.derivative_from_output(*a));
        let (dout, din) = mlp.layers[l].w.shape();
        let prev = if l == 0 {
            DMatrixView::from_slice(xb, din, rows)
        } else {
            post[l - 1].as_view()
        };
        let mut gw = DMatrix::zeros(dout, din);
        gw.gemm(1.0, &dz, &prev.transpose(), 0.0);
        let gb: Vec<f64> = (0..dout).map(|r| dz.row(r).sum()).collect();
        g = if l > 0 {
            let mut gp = DMatrix::zeros(din, rows);
            gp.gemm(1.0, &mlp.layers[l].w.transpose(), &dz, 0.0);
            gp
        } else {
            DMatrix::zeros(0, 0)
        };
        let layer = &mut mlp.layers[l];
        state.update(
            &cfg.optimizer,
            lr,
            2 * l,
            layer.w.as_mut_slice(),
            gw.as_slice(),
        );
        state.update(&cfg.optimizer, lr, 2 * l + 1, layer.b.as_mut_slice(), &gb);
    }
    loss / denom
}

#[cfg(test)]
mod tests;
