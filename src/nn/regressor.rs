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
}
