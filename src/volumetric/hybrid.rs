//! Kinematic model plus a smoothing spline or a small network on its residual.

use super::Error;
use super::data::{Bounds, VolumetricData};
use super::kinematic::KinematicModel;
use super::network::{NetworkMap, NetworkOptions};
use super::pspline::{SmoothingSpline3, default_pieces};
use serde::{Deserialize, Serialize};

/// What the hybrid fits to the kinematic model's residual.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResidualKind {
    /// Tensor-product cubic P-spline, λ by GCV (default: deterministic, milliseconds).
    #[default]
    Spline,
    /// Xiang et al. 2019's and Wang, Dai & Hong's small sigmoid network (3-8-3).
    Network,
}

impl ResidualKind {
    /// Parses `spline` or `network`.
    pub fn parse(s: &str) -> Option<ResidualKind> {
        match s {
            "spline" => Some(ResidualKind::Spline),
            "network" => Some(ResidualKind::Network),
            _ => None,
        }
    }
}

/// `e(p) = kinematic(p) + residual(p)`, the residual part (a smoothing spline, or a
/// 3-8-3 network with sigmoid hidden and linear output on z-scored targets) fitted to
/// what the rigid-body model leaves: elastic sag under the moving masses, thermal bends,
/// anything not a function of one axis. Exactly one of `residual` / `spline` is set
/// (files written before the spline option hold `residual`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HybridModel {
    /// The rigid-body ISO 230-1 part.
    pub kinematic: KinematicModel,
    /// The residual as a 3-8-3 network (files written before the spline option).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual: Option<NetworkMap>,
    /// The residual as a 3-D smoothing spline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spline: Option<SmoothingSpline3>,
}

/// Hidden neurons of the residual network (4 could not learn an 8 µm sag).
pub const RESIDUAL_HIDDEN: usize = 8;

impl HybridModel {
    /// Fits the kinematic model (see [`KinematicModel::fit`]) and then the residual
    /// part on `error − kinematic(node)`: a [`SmoothingSpline3`] with
    /// [`default_pieces`] per axis, or a network (see [`NetworkMap::fit`]).
    ///
    /// Known bad case: on a rigid machine the residual is measurement noise and the
    /// residual part can only add variance (the spline's GCV keeps that small);
    /// cross-validation then prefers the plain kinematic model.
    pub fn fit(
        data: &VolumetricData,
        degree: usize,
        tool_offset_mm: [f64; 3],
        kind: ResidualKind,
        network: &NetworkOptions,
    ) -> Result<HybridModel, Error> {
        let kinematic = KinematicModel::fit(data, degree, tool_offset_mm)?;
        let residual_data = VolumetricData {
            nodes: data.nodes.clone(),
            errors: data
                .nodes
                .iter()
                .zip(&data.errors)
                .map(|(&p, e)| {
                    let k = kinematic.eval(p);
                    [e[0] - k[0], e[1] - k[1], e[2] - k[2]]
                })
                .collect(),
        };
        match kind {
            ResidualKind::Spline => {
                let pieces = [0, 1, 2].map(|k| default_pieces(distinct_levels(data, k)));
                Ok(HybridModel {
                    kinematic,
                    residual: None,
                    spline: Some(SmoothingSpline3::fit(&residual_data, pieces)?),
                })
            }
            ResidualKind::Network => {
                let opts = NetworkOptions {
                    hidden: RESIDUAL_HIDDEN,
                    sigmoid_output: false,
                    ..*network
                };
                Ok(HybridModel {
                    kinematic,
                    residual: Some(NetworkMap::fit(&residual_data, &opts)?),
                    spline: None,
                })
            }
        }
    }

    /// Which residual part this model carries.
    pub fn residual_kind(&self) -> ResidualKind {
        if self.spline.is_some() {
            ResidualKind::Spline
        } else {
            ResidualKind::Network
        }
    }

    /// Predicted errors (mm) at `points` (mm), coordinates clamped into the box.
    pub fn eval_many(&self, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let r: Vec<[f64; 3]> = match (&self.spline, &self.residual) {
            (Some(s), _) => points.iter().map(|&p| s.eval(p)).collect(),
            (None, Some(n)) => n.eval_many(points),
            (None, None) => vec![[0.0; 3]; points.len()],
        };
        points
            .iter()
            .zip(r)
            .map(|(&p, r)| {
                let k = self.kinematic.eval(p);
                [k[0] + r[0], k[1] + r[1], k[2] + r[2]]
            })
            .collect()
    }

    /// Numbers stored by both parts.
    pub fn parameter_count(&self) -> usize {
        self.kinematic.parameter_count()
            + self.residual.as_ref().map_or(0, |n| n.parameter_count())
            + self.spline.as_ref().map_or(0, |s| s.parameter_count())
    }

    /// The fitted box (mm).
    pub fn bounds(&self) -> Bounds {
        self.kinematic.bounds()
    }

    /// Rejects a stored model without a residual part or with a malformed spline.
    pub fn check(&self) -> Result<(), Error> {
        match (&self.spline, &self.residual) {
            (Some(s), None) => s.check(),
            (None, Some(_)) => Ok(()),
            _ => Err(Error::ModelFormat(
                "a hybrid model needs exactly one residual part (spline or network)".into(),
            )),
        }
    }
}

/// Distinct node positions along axis `k` (positions closer than 1e-6 of the span are one).
fn distinct_levels(data: &VolumetricData, k: usize) -> usize {
    let mut v: Vec<f64> = data.nodes.iter().map(|p| p[k]).collect();
    v.sort_by(f64::total_cmp);
    let span = v.last().copied().unwrap_or(0.0) - v.first().copied().unwrap_or(0.0);
    let tol = 1e-6 * span.max(1e-9);
    1 + v.windows(2).filter(|w| w[1] - w[0] > tol).count()
}
