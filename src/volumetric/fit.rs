//! Fitting a map: cross-validation on held-out nodes, the automatic choice, prediction.

use super::Error;
use super::data::{Bounds, VolumetricData};
use super::hybrid::{HybridModel, ResidualKind};
use super::kinematic::KinematicModel;
use super::model::{Model, ModelKind};
use super::network::{NetworkMap, NetworkOptions};
use super::trilinear::TrilinearMap;
use crate::numeric::parallel;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
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
    /// The seeds' network settings.
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

/// Cross-validated score of one model kind.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelScore {
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

/// A fitted volumetric error map with its validation record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumetricMap {
    /// Format version of the serialised map.
    pub version: u32,
    pub model: Model,
    /// Box of the measured nodes (mm); queries outside it are clamped and flagged.
    pub bounds: Bounds,
    pub n_nodes: usize,
    /// How the held-out nodes were chosen.
    pub cv_scheme: String,
    pub scores: Vec<ModelScore>,
    /// RMS length of the residual at the nodes of the chosen model (mm).
    pub fit_rms_mm: f64,
    /// The ISO 230-1 fit used for the 21 component curves (whatever model predicts).
    pub components: Option<KinematicModel>,
    pub options: FitOptions,
}

/// Errors predicted at query points, with the points outside the measured box flagged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    /// `[dx, dy, dz]` (mm) per point.
    pub errors: Vec<[f64; 3]>,
    /// True where the point lies outside the measured box (its error is that of the
    /// nearest point of the box).
    pub out_of_box: Vec<bool>,
}

/// Version 2 (session 3): kinematic models name their error-motion basis (`spline` for new
/// fits); version-1 maps have none and are read as Legendre series, as they were written.
const FORMAT_VERSION: u32 = 2;
/// Oldest map version this build still reads.
const OLDEST_READABLE: u32 = 1;

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

fn fit_kind(kind: ModelKind, data: &VolumetricData, o: &FitOptions) -> Result<Model, Error> {
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

fn length(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Cross-validates one kind over `sets`: fit on the rest, predict the held-out nodes.
fn score(
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
fn choose(scores: &[ModelScore]) -> Option<ModelKind> {
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

/// Fits a volumetric error map to measured nodes.
///
/// Every candidate kind (all four for `auto`, else the one asked for) is scored by
/// cross-validation on held-out nodes (see [`folds`]); `auto` takes the lowest
/// cross-validated RMS error, or within 2 % of it the kinematic model if tied, else the
/// model storing fewest numbers (see `choose`), and refits it on all nodes. The ISO 230-1 model is also
/// fitted for the component curves.
///
/// Reference: seed 001 (network vs the controller's spatial interpolation, FANUC);
/// seed 004 (3-8-3 network, RMSDL/RMSAL); ISO 230-1:2012 (21 error parameters).
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
    scores.extend(slow_scores.map_err(|_| Error::Fit("cross-validation thread panicked".into()))?);
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
    })
}

impl VolumetricMap {
    /// Predicted positioning errors (mm) at `points` (mm), flagging points outside the
    /// measured box (evaluated at the nearest point of the box). Errors: a non-finite
    /// coordinate.
    pub fn predict(&self, points: &[[f64; 3]]) -> Result<Prediction, Error> {
        if let Some(index) = points.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(Error::NonFinite {
                field: "points",
                index,
            });
        }
        Ok(Prediction {
            errors: self.model.eval_many(points),
            out_of_box: points.iter().map(|&p| !self.bounds.contains(p)).collect(),
        })
    }

    /// Predicted error vector (mm) at one point (mm), clamped into the box. For the
    /// part-domain gap diagnosis: the deviation a surface point gets from the machine
    /// is `error_at(p) · n` along the outward normal `n`. A non-finite point gives NaN.
    pub fn error_at(&self, point: [f64; 3]) -> [f64; 3] {
        if point.iter().any(|v| !v.is_finite()) {
            return [f64::NAN; 3];
        }
        self.model.eval_many(&[point])[0]
    }

    /// Serialised map (JSON, versioned) for the model store.
    pub fn to_bytes(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }

    /// Decodes [`VolumetricMap::to_bytes`]. Errors: not a map, or another version.
    pub fn from_bytes(bytes: &[u8]) -> Result<VolumetricMap, Error> {
        let m: VolumetricMap =
            serde_json::from_slice(bytes).map_err(|e| Error::ModelFormat(e.to_string()))?;
        if !(OLDEST_READABLE..=FORMAT_VERSION).contains(&m.version) {
            return Err(Error::ModelFormat(format!(
                "version {} (this build reads {OLDEST_READABLE} to {FORMAT_VERSION})",
                m.version
            )));
        }
        if let Model::Hybrid(h) = &m.model {
            h.check()?;
        }
        Ok(m)
    }
}

/// Deviation (mm) along unit normals that a machine with `map` adds to nominal surface
/// points: `d_k = e(p_k) · n_k` — what the gap diagnosis' part domain uses as the
/// machine's predicted deviation (positive where material is left, as the measurement
/// contract's deviations, when `n` is the outward normal and `e` moves the tool away).
/// `points` and `normals` must have the same length (shorter one bounds the output).
pub fn normal_deviation(
    map: &VolumetricMap,
    points: &[[f64; 3]],
    normals: &[[f64; 3]],
) -> Vec<f64> {
    let e = map.model.eval_many(points);
    e.iter()
        .zip(normals)
        .map(|(e, n)| e[0] * n[0] + e[1] * n[1] + e[2] * n[2])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn score(model: ModelKind, rms_um: f64, params: usize) -> ModelScore {
        ModelScore {
            model,
            cv_rms_mm: Some(rms_um * 1e-3),
            cv_max_mm: None,
            parameter_count: Some(params),
            skipped: None,
        }
    }

    #[test]
    fn auto_prefers_the_kinematic_model_only_within_the_tie_band() {
        use ModelKind::*;
        // a 1.6 % CV lead of the network is a tie: the rigid-body model is kept
        let tie = [
            score(Trilinear, 2.56, 557),
            score(Network, 2.42, 71),
            score(Kinematic, 2.46, 79),
        ];
        assert_eq!(choose(&tie), Some(Kinematic));
        // a clear lead wins whatever it stores
        let clear = [score(Kinematic, 1.06, 79), score(Hybrid, 0.66, 518)];
        assert_eq!(choose(&clear), Some(Hybrid));
        // a tie without the kinematic model: fewest numbers
        let other = [
            score(Kinematic, 3.0, 51),
            score(Trilinear, 2.0, 155),
            score(Network, 2.03, 71),
        ];
        assert_eq!(choose(&other), Some(Network));
        assert_eq!(choose(&[]), None);
    }
    use crate::volumetric::{ShapeFamily, SyntheticMachine};

    fn off_grid_rms(map: &VolumetricMap, m: &SyntheticMachine) -> f64 {
        let pts = m.random_points(1500, 77);
        let pred = map.predict(&pts).unwrap();
        assert!(pred.out_of_box.iter().all(|o| !o));
        let se: f64 = pts
            .iter()
            .zip(&pred.errors)
            .map(|(&p, e)| length(*e, m.error(p)).powi(2))
            .sum();
        (se / pts.len() as f64).sqrt()
    }

    fn quick(model: ModelKind, m: &SyntheticMachine) -> FitOptions {
        let network = NetworkOptions {
            epochs: Some(150),
            ..NetworkOptions::default()
        };
        FitOptions {
            model,
            tool_offset_mm: m.tool_offset_mm,
            network,
            ..FitOptions::default()
        }
    }

    #[test]
    fn auto_beats_the_controller_table_on_a_rigid_machine() {
        // issue 7's goal is ≤ 0.5× trilinear; the bench reports it over 6 machines (mean
        // ≈ 0.5, single machines up to ≈ 0.6 on the coarse grid); this test guards
        // against regressions on two machines, not the goal itself
        for (grid, seed) in [([7, 6, 5], 21), ([4, 4, 3], 22)] {
            let m = SyntheticMachine::new(seed, ShapeFamily::TrendAndWaviness);
            let d = m.measure_grid(grid, seed);
            let auto = fit(&d, &quick(ModelKind::Auto, &m)).unwrap();
            let tri = fit(&d, &quick(ModelKind::Trilinear, &m)).unwrap();
            assert_eq!(auto.scores.len(), 4);
            assert_eq!(auto.model.kind(), ModelKind::Kinematic, "{:?}", auto.scores);
            let (a, t) = (off_grid_rms(&auto, &m), off_grid_rms(&tri, &m));
            assert!(a < 0.7 * t, "{grid:?}: auto {a} vs trilinear {t}");
            assert!(auto.model.parameter_count() < tri.model.parameter_count());
            // cross-validation ranks the same way the truth does
            let cv = |k: ModelKind| {
                auto.scores
                    .iter()
                    .find(|s| s.model == k)
                    .unwrap()
                    .cv_rms_mm
                    .unwrap()
            };
            assert!(cv(ModelKind::Kinematic) < cv(ModelKind::Trilinear));
        }
    }

    #[test]
    fn hybrid_learns_what_a_rigid_model_cannot() {
        let mut m = SyntheticMachine::new(1, ShapeFamily::TrendAndWaviness);
        m.sag_mm = 8e-3;
        let d = m.measure_grid([7, 6, 5], 3);
        let kin = fit(
            &d,
            &FitOptions {
                model: ModelKind::Kinematic,
                tool_offset_mm: m.tool_offset_mm,
                max_folds: 2,
                ..FitOptions::default()
            },
        )
        .unwrap();
        let k = off_grid_rms(&kin, &m);
        // the spline (default) must do better than the network on a smooth sag
        let mut rms = vec![];
        for residual in [ResidualKind::Spline, ResidualKind::Network] {
            let o = FitOptions {
                model: ModelKind::Hybrid,
                residual,
                ..kin.options.clone()
            };
            let hybrid = fit(&d, &o).unwrap();
            let h = off_grid_rms(&hybrid, &m);
            assert!(h < 0.85 * k, "hybrid ({residual:?}) {h} vs kinematic {k}");
            assert_eq!(hybrid.scores.len(), 1);
            let Model::Hybrid(model) = &hybrid.model else {
                panic!("not a hybrid")
            };
            assert_eq!(model.residual_kind(), residual);
            // the stored form round-trips with its residual part
            let back = VolumetricMap::from_bytes(&hybrid.to_bytes()).unwrap();
            let pts = m.random_points(50, 9);
            let (a, b) = (back.model.eval_many(&pts), hybrid.model.eval_many(&pts));
            for (a, b) in a.iter().zip(&b) {
                assert!((0..3).all(|j| (a[j] - b[j]).abs() < 1e-12), "{a:?} {b:?}");
            }
            rms.push(h);
        }
        assert!(rms[0] < rms[1], "spline {} vs network {}", rms[0], rms[1]);
        // a stored hybrid without a residual part is refused, not evaluated as rigid
        let hybrid = fit(
            &d,
            &FitOptions {
                model: ModelKind::Hybrid,
                ..kin.options.clone()
            },
        )
        .unwrap();
        let mut v: serde_json::Value = serde_json::from_slice(&hybrid.to_bytes()).unwrap();
        let removed = v["model"].as_object_mut().and_then(|o| o.remove("spline"));
        assert!(removed.is_some(), "layout changed: {}", v["model"]);
        let err = VolumetricMap::from_bytes(&serde_json::to_vec(&v).unwrap()).unwrap_err();
        assert!(
            err.to_string().contains("exactly one residual part"),
            "{err}"
        );
    }

    #[test]
    fn plane_folds_hold_out_whole_interior_planes() {
        let m = SyntheticMachine::new(3, ShapeFamily::TrendAndWaviness);
        let d = m.measure_grid([4, 4, 3], 1);
        let (scheme, sets) = folds(&d, 8, 0);
        assert!(
            scheme.starts_with("leave-one-interior-plane-out"),
            "{scheme}"
        );
        assert_eq!(sets.len(), 2 + 2 + 1);
        assert_eq!(
            sets.iter().map(Vec::len).collect::<Vec<_>>(),
            vec![12, 12, 12, 12, 16]
        );
        for set in &sets {
            let rest: Vec<usize> = (0..d.nodes.len()).filter(|i| !set.contains(i)).collect();
            assert!(d.subset(&rest).grid().is_ok());
        }
        let (_, capped) = folds(&m.measure_grid([7, 6, 5], 1), 3, 0);
        assert_eq!(capped.len(), 3);
    }

    #[test]
    fn scattered_nodes_skip_trilinear_and_reject_it_when_asked() {
        let m = SyntheticMachine::new(4, ShapeFamily::TrendAndWaviness);
        let d = m.measure(m.random_points(120, 5), 6);
        let o = quick(ModelKind::Auto, &m);
        let map = fit(
            &d,
            &FitOptions {
                max_folds: 5,
                ..o.clone()
            },
        )
        .unwrap();
        assert!(map.cv_scheme.contains("random"));
        let tri = map
            .scores
            .iter()
            .find(|s| s.model == ModelKind::Trilinear)
            .unwrap();
        assert!(
            tri.cv_rms_mm.is_none()
                && tri
                    .skipped
                    .as_deref()
                    .unwrap()
                    .contains("not a full rectilinear grid")
        );
        assert!(matches!(
            fit(
                &d,
                &FitOptions {
                    model: ModelKind::Trilinear,
                    ..o
                }
            ),
            Err(Error::NotAGrid { .. })
        ));
    }

    #[test]
    fn predictions_flag_outside_points_and_the_map_round_trips() {
        let m = SyntheticMachine::new(6, ShapeFamily::TrendAndWaviness);
        let d = m.measure_grid([4, 4, 3], 1);
        let map = fit(&d, &quick(ModelKind::Kinematic, &m)).unwrap();
        let p = map
            .predict(&[[100.0, 100.0, 100.0], [900.0, 100.0, 100.0]])
            .unwrap();
        assert_eq!(p.out_of_box, vec![false, true]);
        assert_eq!(p.errors[1], map.error_at([800.0, 100.0, 100.0]));
        assert_eq!(
            map.predict(&[[0.0, f64::NAN, 0.0]]),
            Err(Error::NonFinite {
                field: "points",
                index: 0
            })
        );
        let back = VolumetricMap::from_bytes(&map.to_bytes()).unwrap();
        assert_eq!(
            back.error_at([10.0, 20.0, 30.0]),
            map.error_at([10.0, 20.0, 30.0])
        );
        let mut v: serde_json::Value = serde_json::from_slice(&map.to_bytes()).unwrap();
        v["version"] = 99.into();
        assert!(matches!(
            VolumetricMap::from_bytes(&serde_json::to_vec(&v).unwrap()),
            Err(Error::ModelFormat(_))
        ));
        let n = [0.0, 0.6, 0.8];
        let e = map.error_at([5.0, 6.0, 7.0]);
        let dev = normal_deviation(&map, &[[5.0, 6.0, 7.0]], &[n]);
        assert!((dev[0] - (e[1] * 0.6 + e[2] * 0.8)).abs() < 1e-15);
    }

    #[test]
    fn version_1_maps_are_read_as_legendre_series() {
        use crate::volumetric::MotionBasis;
        let m = SyntheticMachine::new(2, ShapeFamily::TrendAndWaviness);
        let d = m.measure_grid([7, 6, 5], 1);
        let map = fit(&d, &quick(ModelKind::Kinematic, &m)).unwrap();
        let Model::Kinematic(k) = &map.model else {
            panic!("asked for kinematic")
        };
        assert_eq!(k.basis, MotionBasis::Spline);
        // the same coefficients read as a Legendre series: what a version-1 file meant
        let mut old = map.clone();
        if let Model::Kinematic(k) = &mut old.model {
            k.basis = MotionBasis::Legendre;
        }
        if let Some(c) = old.components.as_mut() {
            c.basis = MotionBasis::Legendre;
        }
        fn strip(v: &mut serde_json::Value) {
            match v {
                serde_json::Value::Object(o) => {
                    o.remove("basis");
                    o.values_mut().for_each(strip);
                }
                serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
                _ => {}
            }
        }
        let mut v: serde_json::Value = serde_json::from_slice(&old.to_bytes()).unwrap();
        strip(&mut v);
        v["version"] = 1.into();
        let back = VolumetricMap::from_bytes(&serde_json::to_vec(&v).unwrap()).unwrap();
        let q = [123.0, 234.0, 345.0];
        assert_eq!(back.error_at(q), old.error_at(q));
        assert_ne!(back.error_at(q), map.error_at(q));
    }

    #[test]
    fn rejects_bad_options_and_data() {
        let m = SyntheticMachine::new(6, ShapeFamily::TrendAndWaviness);
        let d = m.measure_grid([4, 4, 3], 1);
        let o = quick(ModelKind::Kinematic, &m);
        assert!(
            fit(
                &d,
                &FitOptions {
                    degree: 0,
                    ..o.clone()
                }
            )
            .is_err()
        );
        assert!(
            fit(
                &d,
                &FitOptions {
                    tool_offset_mm: [0.0, f64::INFINITY, 0.0],
                    ..o.clone()
                }
            )
            .is_err()
        );
        assert!(matches!(
            fit(&d.subset(&[0, 1, 2]), &o),
            Err(Error::TooFewNodes { .. })
        ));
    }
}
