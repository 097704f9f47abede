//! Gradient-descent optimisers: SGD with momentum (Zhang et al. 2023 eq. 14) and Adam.

use serde::{Deserialize, Serialize};

use super::error::{Error, Result};

/// The update rule applied after each (mini-)batch.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Optimizer {
    /// SGD with momentum, Zhang et al. 2023 eq. 14: `v <- beta v - eta g`, `w <- w + v`.
    Sgd {
        /// Learning rate eta.
        lr: f64,
        /// Momentum beta in [0, 1).
        momentum: f64,
    },
    /// Adam (Kingma & Ba 2015) with bias correction.
    Adam {
        /// Learning rate.
        lr: f64,
        /// First-moment decay (0.9).
        beta1: f64,
        /// Second-moment decay (0.999).
        beta2: f64,
        /// Denominator guard (1e-8).
        eps: f64,
    },
}

impl Optimizer {
    /// Adam with the usual constants and learning rate `lr`.
    pub fn adam(lr: f64) -> Self {
        Optimizer::Adam {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }

    /// Base learning rate.
    pub fn lr(&self) -> f64 {
        match *self {
            Optimizer::Sgd { lr, .. } | Optimizer::Adam { lr, .. } => lr,
        }
    }

    pub(crate) fn validate(&self) -> Result<()> {
        let lr = self.lr();
        if !(lr.is_finite() && lr > 0.0) {
            return Err(Error::InvalidParameter {
                name: "learning rate",
                value: lr,
                reason: "must be > 0",
            });
        }
        match *self {
            Optimizer::Sgd { momentum, .. } if !(0.0..1.0).contains(&momentum) => {
                Err(Error::InvalidParameter {
                    name: "momentum",
                    value: momentum,
                    reason: "must be in [0, 1)",
                })
            }
            Optimizer::Adam {
                beta1, beta2, eps, ..
            } if !(0.0..1.0).contains(&beta1)
                || !(0.0..1.0).contains(&beta2)
                || eps.is_nan()
                || eps <= 0.0 =>
            {
                Err(Error::InvalidParameter {
                    name: "adam beta1/beta2/eps",
                    value: beta1,
                    reason: "betas must be in [0, 1) and eps > 0",
                })
            }
            _ => Ok(()),
        }
    }
}

/// Learning-rate schedule over the epochs of one training run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LrSchedule {
    /// The base rate throughout (Zhang et al. 2023's setting).
    Constant,
    /// Cosine decay from the base rate to `base * final_factor` at the last epoch.
    Cosine {
        /// Ratio of the last epoch's rate to the first's, in (0, 1].
        final_factor: f64,
    },
}

impl LrSchedule {
    /// Learning-rate multiplier for `epoch` (0-based) of `epochs`.
    pub(crate) fn factor(&self, epoch: usize, epochs: usize) -> f64 {
        match *self {
            LrSchedule::Constant => 1.0,
            LrSchedule::Cosine { final_factor } => {
                let p = if epochs <= 1 {
                    0.0
                } else {
                    epoch as f64 / (epochs - 1) as f64
                };
                final_factor + (1.0 - final_factor) * 0.5 * (1.0 + (std::f64::consts::PI * p).cos())
            }
        }
    }
}

/// Per-parameter optimiser memory (velocity or Adam moments), one buffer per tensor.
pub(crate) struct OptimizerState {
    m: Vec<Vec<f64>>,
    v: Vec<Vec<f64>>,
    t: i32,
}

impl OptimizerState {
    pub(crate) fn new(tensor_sizes: &[usize]) -> Self {
        OptimizerState {
            m: tensor_sizes.iter().map(|&n| vec![0.0; n]).collect(),
            v: tensor_sizes.iter().map(|&n| vec![0.0; n]).collect(),
            t: 0,
        }
    }

    /// Call once per batch before the tensor updates.
    pub(crate) fn next_step(&mut self) {
        self.t = self.t.saturating_add(1);
    }

    /// Applies one update to tensor `k` with gradient `g` and the scheduled rate `lr`.
    pub(crate) fn update(&mut self, opt: &Optimizer, lr: f64, k: usize, w: &mut [f64], g: &[f64]) {
        match *opt {
            Optimizer::Sgd { momentum, .. } => {
                for ((wi, vi), gi) in w.iter_mut().zip(self.m[k].iter_mut()).zip(g) {
                    *vi = momentum * *vi - lr * gi;
                    *wi += *vi;
                }
            }
            Optimizer::Adam {
                beta1, beta2, eps, ..
            } => {
                let c1 = 1.0 - beta1.powi(self.t);
                let c2 = 1.0 - beta2.powi(self.t);
                let step = lr * c2.sqrt() / c1;
                for (((wi, mi), vi), gi) in w
                    .iter_mut()
                    .zip(self.m[k].iter_mut())
                    .zip(self.v[k].iter_mut())
                    .zip(g)
                {
                    *mi = beta1 * *mi + (1.0 - beta1) * gi;
                    *vi = beta2 * *vi + (1.0 - beta2) * gi * gi;
                    *wi -= step * *mi / (vi.sqrt() + eps * c2.sqrt());
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
