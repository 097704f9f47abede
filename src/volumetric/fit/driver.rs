//! The fit of a volumetric map: its options and [`fit`], which scores every candidate
//! model by cross-validation, refits the chosen one on all nodes and records how it did.

use super::cv::{ModelScore, choose, fit_kind, folds, length, score};
use super::map::{FORMAT_VERSION, VolumetricMap};
use crate::numeric::parallel;
use crate::volumetric::Error;
use crate::volumetric::data::VolumetricData;
use crate::volumetric::hybrid::ResidualKind;
use crate::volumetric::kinematic::KinematicModel;
use crate::volumetric::model::{Model, ModelKind};
use crate::volumetric::network::NetworkOptions;
use serde::{Deserialize, Serialize};

/// How to fit a map. `Default` is what the service uses when the client says nothing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FitOptions {
    /// Model to fit (default `auto`: best cross-validated RMS).
    pub model: ModelKind,
    /// Abbe offset of the tool tip (or tracker reflector) from the Z carriage (mm).
    pub tool_offset_mm: [f64; 3],
    /// Terms per ISO 230-1 error motion minus one, as a polynomial degree (default 5; capped
    /// per axis at the number of distinct node positions − 1; see [`KinematicModel::fit`]).
    pub degree: usize,
    /// Controller table-size limit for the trilinear model (points per axis).
    pub max_points_per_axis: Option<usize>,
    /// What the hybrid fits to the kinematic residual (default `spline`).
    pub residual: ResidualKind,
    /// Xiang et al. 2019's and Wang, Dai & Hong's network settings.
    pub network: NetworkOptions,
    /// At most this many cross-validation folds (default 8).
    pub max_folds: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            model: ModelKind::Auto,
            tool_offset_mm: [0.0; 3],
            degree: 5,
            max_points_per_axis: None,
            residual: ResidualKind::default(),
            network: NetworkOptions::default(),
            max_folds: 8,
        }
    }
}

/// Fits a volumetric error map to measured nodes.
///
/// Every candidate kind (all four for `auto`, else the one asked for) is scored by
/// cross-validation on held-out nodes (see [`folds`]); `auto` takes the lowest
/// cross-validated RMS error, or within 2 % of it the kinematic model if tied, else the
/// model storing fewest numbers (see `choose`), and refits it on all nodes. The ISO 230-1 model is also
/// fitted for the component curves.
///
/// Reference: Xiang et al. 2019 (network vs the controller's spatial interpolation, FANUC);
/// Wang, Dai & Hong (3-8-3 network, RMSDL/RMSAL); ISO 230-1:2012 (21 error parameters).
/// Errors: invalid data or options; trilinear asked for on scattered nodes.
pub fn fit(data: &VolumetricData, options: &FitOptions) -> Result<VolumetricMap, Error> {
    let bounds = data.validate(8)?;
    if options.degree == 0 || options.degree > 8 {
        return Err(Error::InvalidOption {
            name: "degree",
            reason: "must be between 1 and 8".into(),
        });
    }
    if options.tool_offset_mm.iter().any(|v| !v.is_finite()) {
        return Err(Error::InvalidOption {
            name: "tool_offset_mm",
            reason: "must be finite numbers (mm)".into(),
        });
    }
    if options.model == ModelKind::Trilinear {
        data.grid()?;
    }
    let (cv_scheme, sets) = folds(data, options.max_folds, options.network.seed);
    let kinds: Vec<ModelKind> = match options.model {
        ModelKind::Auto => ModelKind::CONCRETE.to_vec(),
        k => vec![k],
    };
    let score_one = |k: ModelKind| {
        if k == ModelKind::Trilinear
            && let Err(e) = data.grid()
        {
            return ModelScore {
                model: k,
                cv_rms_mm: None,
                cv_max_mm: None,
                parameter_count: None,
                skipped: Some(e.to_string()),
            };
        }
        score(k, data, &sets, options)
    };
    // the two network kinds dominate the time: score them on a second thread
    let (slow, fast): (Vec<ModelKind>, Vec<ModelKind>) =
        kinds.iter().partition(|k| matches!(k, ModelKind::Network));
    let (slow_scores, mut scores) = parallel::join(
        || slow.iter().map(|&k| score_one(k)).collect::<Vec<_>>(),
        || {
            fast.iter()
                .map(|&k| score_one(k))
                .collect::<Vec<ModelScore>>()
        },
    );
    let slow_scores = match slow_scores {
        Ok(s) => s,
        // a stopped fit (cancelled, or out of time) ends as a stop, not as a fit error
        Err(p) if p.is::<crate::numeric::stop::Stopped>() => std::panic::resume_unwind(p),
        Err(_) => return Err(Error::Fit("cross-validation thread panicked".into())),
    };
    scores.extend(slow_scores);
    scores.sort_by_key(|s| ModelKind::CONCRETE.iter().position(|&k| k == s.model));
    let chosen = match options.model {
        ModelKind::Auto => choose(&scores).unwrap_or(ModelKind::Kinematic),
        k => k,
    };
    let model = fit_kind(chosen, data, options)?;
    if let Some(s) = scores.iter_mut().find(|s| s.model == chosen) {
        s.parameter_count = Some(model.parameter_count());
    }
    let fitted = model.eval_many(&data.nodes);
    let fit_rms_mm = (fitted
        .iter()
        .zip(&data.errors)
        .map(|(p, e)| length(*p, *e).powi(2))
        .sum::<f64>()
        / data.nodes.len() as f64)
        .sqrt();
    let components = match &model {
        Model::Kinematic(k) => Some(k.clone()),
        Model::Hybrid(h) => Some(h.kinematic.clone()),
        _ => KinematicModel::fit(data, options.degree, options.tool_offset_mm).ok(),
    };
    Ok(VolumetricMap {
        version: FORMAT_VERSION,
        model,
        bounds,
        n_nodes: data.nodes.len(),
        cv_scheme,
        scores,
        fit_rms_mm,
        components,
        options: options.clone(),
        truecut_version: None,
    })
}
