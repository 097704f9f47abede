//! Kinematic model plus a small network on its residual.

use super::Error;
use super::data::{Bounds, VolumetricData};
use super::kinematic::KinematicModel;
use super::network::{NetworkMap, NetworkOptions};
use serde::{Deserialize, Serialize};

/// `e(p) = kinematic(p) + network(p)`, the network (3-8-3, sigmoid hidden, linear
/// output on z-scored targets) trained on what the rigid-body model leaves: elastic
/// sag under the moving masses, thermal bends, anything not a function of one axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HybridModel {
    pub kinematic: KinematicModel,
    pub residual: NetworkMap,
}

/// Hidden neurons of the residual network (4 could not learn an 8 µm sag).
pub const RESIDUAL_HIDDEN: usize = 8;

impl HybridModel {
    /// Fits the kinematic model (see [`KinematicModel::fit`]) and then the residual
    /// network (see [`NetworkMap::fit`]) on `error − kinematic(node)`.
    ///
    /// Known bad case: on a rigid machine the residual is measurement noise and the
    /// network can only add variance; cross-validation then prefers the plain
    /// kinematic model.
    pub fn fit(
        data: &VolumetricData,
        degree: usize,
        tool_offset_mm: [f64; 3],
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
        let opts = NetworkOptions {
            hidden: RESIDUAL_HIDDEN,
            sigmoid_output: false,
            ..*network
        };
        let residual = NetworkMap::fit(&residual_data, &opts)?;
        Ok(HybridModel {
            kinematic,
            residual,
        })
    }

    /// Predicted errors (mm) at `points` (mm), coordinates clamped into the box.
    pub fn eval_many(&self, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let r = self.residual.eval_many(points);
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
        self.kinematic.parameter_count() + self.residual.parameter_count()
    }

    /// The fitted box (mm).
    pub fn bounds(&self) -> Bounds {
        self.kinematic.bounds()
    }
}
