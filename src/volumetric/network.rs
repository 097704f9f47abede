//! Xiang et al. 2019's and Wang, Dai & Hong's network: one hidden sigmoid layer, 3-8-3, z-scored
//! inputs, trained by back-propagation (Xiang et al. 2019 steps 2–3; Wang, Dai & Hong §1–2).

use super::Error;
use super::data::{Bounds, VolumetricData};
use crate::nn::{Activation, Init, LrSchedule, Mlp, Optimizer, Regressor, TrainConfig, ZScore};
use serde::{Deserialize, Serialize};

/// Options of the network map.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NetworkOptions {
    /// Hidden neurons (Wang, Dai & Hong: 8).
    pub hidden: usize,
    /// Sigmoid on the output layer too, as both Xiang et al. 2019 and Wang, Dai & Hong do (targets
    /// min–max scaled into [0.1, 0.9]); false: a linear output on z-scored targets.
    pub sigmoid_output: bool,
    /// Training epochs; `None` picks `clamp(600 000 / n, 20, 3 000)` for `n` nodes, a
    /// budget of about 40 000 mini-batch steps (fewer steps left the 3-8-3 network
    /// clearly under-trained on the synthetic machines).
    pub epochs: Option<usize>,
    /// Seed of the weights and the shuffling.
    pub seed: u64,
}

impl Default for NetworkOptions {
    fn default() -> Self {
        NetworkOptions {
            hidden: 8,
            sigmoid_output: true,
            epochs: None,
            seed: 1,
        }
    }
}

/// A trained network map. Serialised with the network in the `nn` file format (hex).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "NetworkRepr", into = "NetworkRepr")]
pub struct NetworkMap {
    regressor: Regressor,
    bounds: Bounds,
}

#[derive(Serialize, Deserialize)]
struct NetworkRepr {
    bounds: Bounds,
    network_hex: String,
}

impl From<NetworkMap> for NetworkRepr {
    fn from(m: NetworkMap) -> Self {
        let bytes = m.regressor.to_bytes();
        NetworkRepr {
            bounds: m.bounds,
            network_hex: bytes.iter().map(|b| format!("{b:02x}")).collect(),
        }
    }
}

impl TryFrom<NetworkRepr> for NetworkMap {
    type Error = Error;
    fn try_from(r: NetworkRepr) -> Result<Self, Error> {
        let hex = r.network_hex.as_bytes();
        if hex.len() % 2 != 0 {
            return Err(Error::ModelFormat("network_hex has odd length".into()));
        }
        let bytes = hex
            .chunks(2)
            .map(|c| {
                std::str::from_utf8(c)
                    .ok()
                    .and_then(|s| u8::from_str_radix(s, 16).ok())
            })
            .collect::<Option<Vec<u8>>>()
            .ok_or_else(|| Error::ModelFormat("network_hex is not hexadecimal".into()))?;
        let regressor =
            Regressor::from_bytes(&bytes).map_err(|e| Error::ModelFormat(e.to_string()))?;
        Ok(NetworkMap {
            regressor,
            bounds: r.bounds,
        })
    }
}

/// Row-major copies of points and errors for the `nn` API.
fn flatten(xs: &[[f64; 3]]) -> Vec<f64> {
    xs.iter().flat_map(|p| p.iter().copied()).collect()
}

impl NetworkMap {
    /// Trains the network on `data` (nodes → errors) with mean-squared-error loss and
    /// back-propagation (Adam, cosine-decayed learning rate 0.01→1e-4, mini-batches of
    /// 16), Xiang et al. 2019's and Wang, Dai & Hong's 3-h-3 topology with sigmoid hidden neurons.
    ///
    /// Reference: Xiang et al. 2019 steps (2)–(3) (`b_h = f(α_h − γ_h)`, `y_j = f(β_j − θ_j)`,
    /// `f(x) = 1/(1+e^−x)`, BP updates of weights and thresholds); Wang, Dai & Hong §2 (3-8-3).
    /// Xiang et al. 2019 and Wang, Dai & Hong stop at a loss target (Wang, Dai & Hong: SSE < 0.001)
    /// or fixed epochs; we use a fixed budget of steps. Known bad cases: a few nodes (< 10) give an
    /// under-determined network (59 weights for 3-8-3); the network does not reproduce
    /// the nodes exactly and smooths sharp features.
    pub fn fit(data: &VolumetricData, opts: &NetworkOptions) -> Result<NetworkMap, Error> {
        if opts.hidden == 0 || opts.hidden > 64 {
            return Err(Error::InvalidOption {
                name: "hidden",
                reason: "must be between 1 and 64".into(),
            });
        }
        let bounds = data.validate(4)?;
        let n = data.nodes.len();
        let epochs = opts.epochs.unwrap_or((600_000 / n).clamp(20, 3_000));
        if epochs == 0 {
            return Err(Error::InvalidOption {
                name: "epochs",
                reason: "must be at least 1".into(),
            });
        }
        let x = flatten(&data.nodes);
        let y = flatten(&data.errors);
        let nnerr = |e: crate::nn::Error| Error::Fit(format!("network: {e}"));
        let x_scaler = ZScore::fit(&x, 3).map_err(nnerr)?;
        let (out, y_scaler) = if opts.sigmoid_output {
            // min–max into [0.1, 0.9] written as a (mean, std) scaler: (y − mean)/std
            let mut s = ZScore::identity(3);
            for j in 0..3 {
                let lo = data
                    .errors
                    .iter()
                    .map(|e| e[j])
                    .fold(f64::INFINITY, f64::min);
                let hi = data
                    .errors
                    .iter()
                    .map(|e| e[j])
                    .fold(f64::NEG_INFINITY, f64::max);
                let std = if hi > lo { (hi - lo) / 0.8 } else { 1.0 };
                s.std[j] = std;
                s.mean[j] = lo - 0.1 * std;
            }
            (Activation::Sigmoid, s)
        } else {
            (Activation::Identity, ZScore::fit(&y, 3).map_err(nnerr)?)
        };
        let mlp = Mlp::new(
            &[3, opts.hidden, 3],
            Activation::Sigmoid,
            out,
            Init::Xavier,
            opts.seed,
        )
        .map_err(nnerr)?;
        let mut regressor = Regressor::new(mlp, x_scaler, y_scaler).map_err(nnerr)?;
        let cfg = TrainConfig {
            epochs,
            batch_size: 16,
            dropout: 0.0,
            optimizer: Optimizer::adam(0.01),
            schedule: LrSchedule::Cosine { final_factor: 0.01 },
            patience: None,
            seed: opts.seed,
        };
        regressor
            .fine_tune(&x, &y, None, &cfg, &mut |_| true)
            .map_err(nnerr)?;
        Ok(NetworkMap { regressor, bounds })
    }

    /// Predicted errors (mm) at `points` (mm); coordinates outside the trained box are
    /// clamped into it (a sigmoid network extrapolates to flat but arbitrary values).
    pub fn eval_many(&self, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let x: Vec<f64> = points.iter().flat_map(|&p| self.bounds.clamp(p)).collect();
        match self.regressor.predict(&x) {
            Ok(y) => y.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            // inputs are finite and of the right width, so predict cannot fail
            Err(_) => vec![[f64::NAN; 3]; points.len()],
        }
    }

    /// Weights, thresholds and the six input and six output scaler numbers.
    pub fn parameter_count(&self) -> usize {
        self.regressor.mlp().n_parameters() + 12
    }

    /// The trained box (mm).
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }
}

#[cfg(test)]
mod tests;
