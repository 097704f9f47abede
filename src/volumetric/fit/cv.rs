//! Cross-validation of the candidate models: held-out node sets (whole interior planes on
//! a grid, random folds otherwise), the score of one kind, and the automatic choice among
//! the scored kinds.

use super::driver::FitOptions;
use crate::volumetric::Error;
use crate::volumetric::data::VolumetricData;
use crate::volumetric::hybrid::HybridModel;
use crate::volumetric::kinematic::KinematicModel;
use crate::volumetric::model::{Model, ModelKind};
use crate::volumetric::network::NetworkMap;
use crate::volumetric::trilinear::TrilinearMap;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use serde::{Deserialize, Serialize};

/// Cross-validated score of one model kind.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelScore {
    /// The model kind scored.
    pub model: ModelKind,
    /// RMS over held-out nodes of the length of (predicted − measured) error (mm).
    pub cv_rms_mm: Option<f64>,
    /// Largest such length (mm).
    pub cv_max_mm: Option<f64>,
    /// Numbers stored: for the chosen model when fitted on all nodes, for the others
    /// the largest over the cross-validation fits.
    pub parameter_count: Option<usize>,
    /// Why the kind was not scored (e.g. trilinear on scattered nodes).
    pub skipped: Option<String>,
}

/// Held-out node sets. On a full grid: whole interior planes (x-, y- or z-levels) —
/// every remaining set is still a grid, so trilinear can be scored, and a held-out
/// node is always off the training grid, as the points a map is used at are. On
/// scattered nodes: 5 random folds.
pub fn folds(data: &VolumetricData, max_folds: usize, seed: u64) -> (String, Vec<Vec<usize>>) {
    let max_folds = max_folds.max(2);
    if let Ok(g) = data.grid() {
        let n = [g.levels[0].len(), g.levels[1].len(), g.levels[2].len()];
        let mut planes: Vec<(usize, usize)> = Vec::new();
        for (k, &nk) in n.iter().enumerate() {
            planes.extend((1..nk.saturating_sub(1)).map(|i| (k, i)));
        }
        if !planes.is_empty() {
            let total = planes.len();
            if total > max_folds {
                planes = (0..max_folds)
                    .map(|f| planes[f * total / max_folds])
                    .collect();
            }
            let sets = planes
                .iter()
                .map(|&(k, i)| {
                    let mut held = Vec::new();
                    for iz in 0..n[2] {
                        for iy in 0..n[1] {
                            for ix in 0..n[0] {
                                if [ix, iy, iz][k] == i {
                                    held.push(g.node_of[ix + n[0] * (iy + n[1] * iz)]);
                                }
                            }
                        }
                    }
                    held
                })
                .collect();
            return (
                format!(
                    "leave-one-interior-plane-out ({} of {} planes)",
                    planes.len(),
                    total
                ),
                sets,
            );
        }
    }
    let k = 5.min(data.nodes.len());
    let mut order: Vec<usize> = (0..data.nodes.len()).collect();
    order.shuffle(&mut StdRng::seed_from_u64(seed));
    let sets = (0..k)
        .map(|f| order.iter().skip(f).step_by(k).copied().collect())
        .collect();
    (format!("{k}-fold random"), sets)
}

pub(super) fn fit_kind(
    kind: ModelKind,
    data: &VolumetricData,
    o: &FitOptions,
) -> Result<Model, Error> {
    Ok(match kind {
        ModelKind::Trilinear => Model::Trilinear(TrilinearMap::fit(data, o.max_points_per_axis)?),
        ModelKind::Network => Model::Network(NetworkMap::fit(data, &o.network)?),
        ModelKind::Kinematic => {
            Model::Kinematic(KinematicModel::fit(data, o.degree, o.tool_offset_mm)?)
        }
        ModelKind::Hybrid => Model::Hybrid(HybridModel::fit(
            data,
            o.degree,
            o.tool_offset_mm,
            o.residual,
            &o.network,
        )?),
        ModelKind::Auto => return Err(Error::UnknownModel("auto is not a concrete model".into())),
    })
}

pub(super) fn length(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Cross-validates one kind over `sets`: fit on the rest, predict the held-out nodes.
pub(super) fn score(
    kind: ModelKind,
    data: &VolumetricData,
    sets: &[Vec<usize>],
    o: &FitOptions,
) -> ModelScore {
    let mut sum = 0.0;
    let mut max = 0.0f64;
    let mut count = 0usize;
    let mut params = 0usize;
    let mut held = vec![false; data.nodes.len()];
    for set in sets {
        crate::numeric::stop::check();
        held.iter_mut().for_each(|h| *h = false);
        set.iter().for_each(|&i| held[i] = true);
        let train: Vec<usize> = (0..data.nodes.len()).filter(|&i| !held[i]).collect();
        let model = match fit_kind(kind, &data.subset(&train), o) {
            Ok(m) => m,
            Err(e) => {
                return ModelScore {
                    model: kind,
                    cv_rms_mm: None,
                    cv_max_mm: None,
                    parameter_count: None,
                    skipped: Some(e.to_string()),
                };
            }
        };
        params = params.max(model.parameter_count());
        let test = data.subset(set);
        for (p, e) in model.eval_many(&test.nodes).into_iter().zip(&test.errors) {
            let d = length(p, *e);
            sum += d * d;
            max = max.max(d);
            count += 1;
        }
    }
    let rms = (count > 0).then(|| (sum / count as f64).sqrt());
    ModelScore {
        model: kind,
        cv_rms_mm: rms,
        cv_max_mm: rms.map(|_| max),
        parameter_count: Some(params),
        skipped: None,
    }
}

/// Tie band: models within this factor of the best cross-validated RMS are taken as equally
/// good (differences that small are within the noise of the CV); see `choose`.
pub const CV_TIE: f64 = 1.02;

/// The kind `auto` picks among the scored kinds whose CV RMS is within [`CV_TIE`] of the
/// best: the rigid-body (kinematic) model if it is among them, else the one storing the
/// fewest numbers.
///
/// Why the kinematic model first: held-out planes are few, so CV RMS differences of a
/// few per cent are noise, and between such a tie the physical model is the safer choice
/// off the grid (it obeys the machine's geometry; a network's stored numbers are not a
/// measure of its simplicity). On the bench's 20 machines (fine grid) a 1.6 % CV lead of
/// the network once chose a map with twice the kinematic model's off-grid error.
pub(super) fn choose(scores: &[ModelScore]) -> Option<ModelKind> {
    let best = scores
        .iter()
        .filter_map(|s| s.cv_rms_mm)
        .min_by(f64::total_cmp)?;
    let tied: Vec<&ModelScore> = scores
        .iter()
        .filter(|s| s.cv_rms_mm.is_some_and(|r| r <= best * CV_TIE))
        .collect();
    if tied.iter().any(|s| s.model == ModelKind::Kinematic) {
        return Some(ModelKind::Kinematic);
    }
    tied.iter()
        .min_by_key(|s| s.parameter_count.unwrap_or(usize::MAX))
        .map(|s| s.model)
}
