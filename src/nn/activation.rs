//! Activation functions.

use serde::{Deserialize, Serialize};

/// Element-wise activation of a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// `max(0, z)` (Zhang et al. 2023 eq. 3).
    Relu,
    /// Logistic `1 / (1 + e^-z)` (Xiang et al. 2019 and Wang, Dai & Hong).
    Sigmoid,
    /// `z` (regression output layers).
    Identity,
}

impl Activation {
    /// The activation `a = f(z)` of a pre-activation `z` (dimensionless).
    ///
    /// Reference: Zhang et al. 2023 eq. 3 for ReLU. Sigmoid saturates (derivative ~0) for |z| > 30.
    #[inline]
    pub fn apply(self, z: f64) -> f64 {
        match self {
            Activation::Relu => z.max(0.0),
            Activation::Sigmoid => 1.0 / (1.0 + (-z).exp()),
            Activation::Identity => z,
        }
    }

    /// The derivative `f'(z)` written in terms of the output `a = f(z)`, which is what
    /// back-propagation keeps: ReLU `1[a > 0]`, sigmoid `a (1 - a)`, identity `1`.
    ///
    /// Reference: standard back-propagation (Zhang et al. 2023 eqs. 5–6). ReLU at exactly 0 takes
    /// 0.
    #[inline]
    pub fn derivative_from_output(self, a: f64) -> f64 {
        match self {
            Activation::Relu => {
                if a > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Activation::Sigmoid => a * (1.0 - a),
            Activation::Identity => 1.0,
        }
    }

    pub(crate) fn code(self) -> u8 {
        match self {
            Activation::Relu => 0,
            Activation::Sigmoid => 1,
            Activation::Identity => 2,
        }
    }

    pub(crate) fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Activation::Relu),
            1 => Some(Activation::Sigmoid),
            2 => Some(Activation::Identity),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests;
