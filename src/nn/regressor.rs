//! A network with its input and output z-score scalers: train, fine-tune, predict, save.

use super::activation::Activation;
use super::error::{Error, Result, check_finite};
use super::fast::Packed32;
use super::format;
use super::mlp::Mlp;
use super::scaler::ZScore;
use super::train::{EpochStats, TrainConfig, TrainReport, train};
use crate::numeric::parallel;

/// An [`Mlp`] wrapped with z-score scalers on inputs and outputs (Zhang et al. 2023 eq. 7), so
/// callers work in physical units. The scalers are fitted once on the first training set and kept
/// when fine-tuning (a fine-tuned model reads inputs exactly as its base did).
#[derive(Clone, Debug, PartialEq)]
pub struct Regressor {
    mlp: Mlp,
    x_scaler: ZScore,
    y_scaler: ZScore,
    /// Free text stored with the model (callers put JSON: feature layout, units, history).
    pub metadata: String,
    /// The network packed for the f32 inference kernel, with the input scaler and (linear
    /// output) the output scaler applied in f64 around it.
    fast: Packed32,
}

impl Regressor {
    /// Wraps a network and its scalers. Errors when the scaler widths do not match the network.
    pub fn new(mlp: Mlp, x_scaler: ZScore, y_scaler: ZScore) -> Result<Self> {
        if x_scaler.cols() != mlp.n_inputs() || y_scaler.cols() != mlp.n_outputs() {
            return Err(Error::Incompatible(format!(
                "scalers have {} / {} columns but the network has {} inputs / {} outputs",
                x_scaler.cols(),
                y_scaler.cols(),
                mlp.n_inputs(),
                mlp.n_outputs()
            )));
        }
        let fast = pack(&mlp, &x_scaler, &y_scaler);
        Ok(Regressor {
            mlp,
            x_scaler,
            y_scaler,
            metadata: String::new(),
            fast,
        })
    }

    /// Fits the scalers on `x`, `y` (row-major, physical units), then trains `mlp` (freshly
    /// initialised by [`Mlp::new`]) with `cfg`. `validation` (physical units) drives early
    /// stopping and best-epoch restore. See [`train`] for the callback.
    pub fn fit(
        mlp: Mlp,
        x: &[f64],
        y: &[f64],
        validation: Option<(&[f64], &[f64])>,
        cfg: &TrainConfig,
        on_epoch: &mut dyn FnMut(&EpochStats) -> bool,
    ) -> Result<(Self, TrainReport)> {
        let x_scaler = ZScore::fit(x, mlp.n_inputs())?;
        let y_scaler = ZScore::fit(y, mlp.n_outputs())?;
        let mut reg = Regressor::new(mlp, x_scaler, y_scaler)?;
        let report = reg.fine_tune(x, y, validation, cfg, on_epoch)?;
        Ok((reg, report))
    }

    /// Continues training on new data with the existing scalers (transfer learning: the
    /// seed's 1/5/10/15 % fine-tuning). Same arguments as [`Regressor::fit`].
    pub fn fine_tune(
        &mut self,
        x: &[f64],
        y: &[f64],
        validation: Option<(&[f64], &[f64])>,
        cfg: &TrainConfig,
        on_epoch: &mut dyn FnMut(&EpochStats) -> bool,
    ) -> Result<TrainReport> {
        if x.len() % self.n_inputs() != 0 {
            return Err(Error::Shape {
                what: "inputs (multiple of the input size)",
                expected: self.n_inputs(),
                got: x.len(),
            });
        }
        let xs = self.x_scaler.transform(x);
        let ys = self.y_scaler.transform(y);
        let val =
            validation.map(|(vx, vy)| (self.x_scaler.transform(vx), self.y_scaler.transform(vy)));
        let report = train(
            &mut self.mlp,
            &xs,
            &ys,
            val.as_ref().map(|(a, b)| (&a[..], &b[..])),
            cfg,
            on_epoch,
        )?;
        self.fast = pack(&self.mlp, &self.x_scaler, &self.y_scaler);
        Ok(report)
    }

    /// Predicts row-major `n x n_outputs` in physical units from row-major `n x n_inputs`, on
    /// the calling thread: inputs z-scored in f64, the network in f32 (AVX2+FMA when the CPU
    /// has them; see the kernel's notes on precision: ~1e-6 relative to the output scale),
    /// outputs unscaled in f64. Reference: Zhang et al. 2023 eqs. 2, 3 and 7.
    /// Errors: wrong length, non-finite inputs.
    pub fn predict(&self, x: &[f64]) -> Result<Vec<f64>> {
        let n = self.mlp.rows(x)?;
        let mut y = vec![0.0; n * self.n_outputs()];
        if !self.fast.forward(x, &mut y) {
            check_finite("network input", x)?;
        }
        self.finish(&mut y);
        Ok(y)
    }

    /// Like [`Regressor::predict`], over up to `threads` threads (0 = all cores); worth it
    /// from about 10,000 samples.
    pub fn predict_parallel(&self, x: &[f64], threads: usize) -> Result<Vec<f64>> {
        let n = self.mlp.rows(x)?;
        let (ni, no) = (self.n_inputs(), self.n_outputs());
        let mut y = vec![0.0; n * no];
        let per = parallel::chunk_len(n, threads, 4096);
        let fast = &self.fast;
        let ok =
            parallel::zip_chunks_mut(x, per * ni, &mut y, per * no, |xc, yc| fast.forward(xc, yc))
                .into_iter()
                .all(|ok| ok);
        if !ok {
            check_finite("network input", x)?;
        }
        self.finish(&mut y);
        Ok(y)
    }

    fn finish(&self, y: &mut [f64]) {
        if self.mlp.layers.last().map(|l| l.activation) != Some(Activation::Identity) {
            self.y_scaler.inverse_in_place(y);
        }
    }

    /// Mean squared error in physical units on `x`, `y`.
    pub fn mse(&self, x: &[f64], y: &[f64]) -> Result<f64> {
        check_finite("targets", y)?;
        let p = self.predict(x)?;
        if p.len() != y.len() {
            return Err(Error::Shape {
                what: "targets",
                expected: p.len(),
                got: y.len(),
            });
        }
        Ok(p.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / y.len().max(1) as f64)
    }

    /// The network in scaled units.
    pub fn mlp(&self) -> &Mlp {
        &self.mlp
    }

    /// Input scaler.
    pub fn x_scaler(&self) -> &ZScore {
        &self.x_scaler
    }

    /// Output scaler.
    pub fn y_scaler(&self) -> &ZScore {
        &self.y_scaler
    }

    /// Inputs per sample.
    pub fn n_inputs(&self) -> usize {
        self.mlp.n_inputs()
    }

    /// Outputs per sample.
    pub fn n_outputs(&self) -> usize {
        self.mlp.n_outputs()
    }

    /// Encodes the model in the compact binary format (see [`super::FORMAT_VERSION`]).
    pub fn to_bytes(&self) -> Vec<u8> {
        format::encode(&self.mlp, &self.x_scaler, &self.y_scaler, &self.metadata)
    }

    /// Decodes a model written by [`Regressor::to_bytes`]. Errors on a bad magic, an
    /// unknown version, truncation or a checksum mismatch.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        let (mlp, xs, ys, metadata) = format::decode(bytes)?;
        let mut r = Regressor::new(mlp, xs, ys)?;
        r.metadata = metadata;
        Ok(r)
    }
}

/// Packs the network for [`Packed32`]: the input scaler always, the output scaler when the
/// last layer is linear (otherwise [`Regressor::finish`] applies it after the activation).
fn pack(mlp: &Mlp, xs: &ZScore, ys: &ZScore) -> Packed32 {
    let no = mlp.n_outputs();
    let linear = mlp.layers.last().map(|l| l.activation) == Some(Activation::Identity);
    let (scale, shift) = if linear {
        (ys.std.clone(), ys.mean.clone())
    } else {
        (vec![1.0; no], vec![0.0; no])
    };
    Packed32::new(mlp, (&xs.mean, &xs.std), (&scale, &shift))
}

#[cfg(test)]
mod tests;
