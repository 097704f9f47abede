//! Weight initialisation schemes.

use nalgebra::{DMatrix, DVector};
use rand::RngExt;
use rand::rngs::Xoshiro256PlusPlus;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// How the weights of a new layer are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Init {
    /// He (Kaiming) normal: `w ~ N(0, 2 / fan_in)`, biases 0. Default for ReLU.
    He,
    /// Glorot (Xavier) normal: `w ~ N(0, 2 / (fan_in + fan_out))`, biases 0. For sigmoid.
    Xavier,
    /// Zhang et al. 2023's choice: `w ~ N(0, 1)` and biases `U(-1/sqrt(fan_in), 1/sqrt(fan_in))`
    /// (Zhang et al. 2023 Step 4, eqs. 10–11; the paper leaves the uniform bounds c, d open).
    /// Badly scaled for anything but tiny layers: activations grow like sqrt(fan_in).
    StandardNormal,
}

impl Init {
    /// Draws a `fan_out x fan_in` weight matrix and a bias vector.
    ///
    /// Reference: He et al. 2015; Glorot & Bengio 2010; Zhang et al. 2023 eqs. 10–11.
    pub(crate) fn draw(
        self,
        fan_in: usize,
        fan_out: usize,
        rng: &mut Xoshiro256PlusPlus,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let std = match self {
            Init::He => (2.0 / fan_in as f64).sqrt(),
            Init::Xavier => (2.0 / (fan_in + fan_out) as f64).sqrt(),
            Init::StandardNormal => 1.0,
        };
        let w = DMatrix::from_fn(fan_out, fan_in, |_, _| {
            let n: f64 = StandardNormal.sample(rng);
            std * n
        });
        let b = match self {
            Init::StandardNormal => {
                let bound = 1.0 / (fan_in as f64).sqrt();
                DVector::from_fn(fan_out, |_, _| rng.random_range(-bound..bound))
            }
            _ => DVector::zeros(fan_out),
        };
        (w, b)
    }
}
