//! A network with its input and output z-score scalers: train, fine-tune, predict, save.

use super::activation::Activation;
use super::error::{Error, Result, check_finite};
use super::format;
use super::mlp::Mlp;
use super::scaler::ZScore;
use super::train::{EpochStats, TrainConfig, TrainReport, train};

/// An [`Mlp`] wrapped with z-score scalers on inputs and outputs (seed 000 eq. 7), so callers
/// work in physical units. The scalers are fitted once on the first training set and kept
/// when fine-tuning (a fine-tuned model reads inputs exactly as its base did).
#[derive(Clone, Debug, PartialEq)]
pub struct Regressor {
    mlp: Mlp,
    x_scaler: ZScore,
    y_scaler: ZScore,
    /// Free text stored with the model (callers put JSON: feature layout, units, history).
    pub metadata: String,
    /// The same network with both scalers folded into its first and last layers, for speed.
    folded: Mlp,
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
        let folded = fold(&mlp, &x_scaler, &y_scaler);
        Ok(Regressor {
            mlp,
            x_scaler,
            y_scaler,
            metadata: String::new(),
            folded,
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
        self.folded = fold(&self.mlp, &self.x_scaler, &self.y_scaler);
        Ok(report)
    }

    /// Predicts row-major `n x n_outputs` in physical units from row-major `n x n_inputs`.
    /// Errors: wrong length, non-finite inputs.
    pub fn predict(&self, x: &[f64]) -> Result<Vec<f64>> {
        let mut y = self.folded.predict(x)?;
        self.finish(&mut y);
        Ok(y)
    }

    /// Like [`Regressor::predict`], over up to `threads` threads (0 = all cores).
    pub fn predict_parallel(&self, x: &[f64], threads: usize) -> Result<Vec<f64>> {
        let mut y = self.folded.predict_parallel(x, threads)?;
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

/// Folds `x_scaled = (x - mu) / S` into the first layer (`W' = W / S`, `b' = b - W' mu`) and,
/// when the last layer is linear, `y = y_scaled * S_y + mu_y` into the last one.
fn fold(mlp: &Mlp, xs: &ZScore, ys: &ZScore) -> Mlp {
    let mut m = mlp.clone();
    {
        let first = &mut m.layers[0];
        for c in 0..first.w.ncols() {
            let s = xs.std[c];
            for r in 0..first.w.nrows() {
                first.w[(r, c)] /= s;
            }
        }
        let shift = &first.w * nalgebra::DVector::from_column_slice(&xs.mean);
        first.b -= shift;
    }
    let last = m.layers.len() - 1;
    let l = &mut m.layers[last];
    if l.activation == Activation::Identity {
        for r in 0..l.w.nrows() {
            let s = ys.std[r];
            for c in 0..l.w.ncols() {
                l.w[(r, c)] *= s;
            }
            l.b[r] = l.b[r] * s + ys.mean[r];
        }
    }
    m
}

#[cfg(test)]
mod tests {
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
        // folded prediction == explicit scaling
        let mut xs = reg.x_scaler().transform(&x);
        let p_explicit = {
            let mut p = reg.mlp().predict(&xs).unwrap();
            reg.y_scaler().inverse_in_place(&mut p);
            p
        };
        let p = reg.predict(&x).unwrap();
        for (a, b) in p.iter().zip(&p_explicit) {
            assert!((a - b).abs() < 1e-9 * (1.0 + b.abs()));
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
        assert!((r2.predict(&x[..2]).unwrap()[0] - (raw[0] * 2.0 + 1.0)).abs() < 1e-12);
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
}
