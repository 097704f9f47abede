//! One entry point for every method and grid order: what the API and the CLI call.

use super::coarse_to_fine::{
    CoarseToFineParams, CoarseToFineResult, coarse_to_fine, narrow_band_part,
};
use super::emd::emd;
use super::error::{Error, check_signal};
use super::field2d::{MAX_SIDE_2D, Order, check_grid, flatten, unflatten, whittaker_2d};
use super::flyers;
use super::screen::{screen, sum_selected};
use super::vmd::{VmdParams, choose_k, vmd};
use super::wavelet::{Wavelet, denoise};
use super::whittaker::Smoothed;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Decomposition method (openapi.yaml `POST /v1/decompose`). `coarse_to_fine` is the default; the
/// others are the single-method baselines of Chen et al. 2024's Table 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The five-stage pipeline of [`coarse_to_fine()`] (VMD, EMD, wavelet, refinement).
    #[default]
    CoarseToFine,
    /// VMD alone: the modes whose |r| against the signal passes the threshold.
    Vmd,
    /// EMD alone: the IMFs and residue whose |r| passes the threshold.
    Emd,
    /// Wavelet soft-threshold denoising alone.
    Wavelet,
}

impl Method {
    /// The wire name.
    pub fn as_str(&self) -> &'static str {
        match self {
            Method::CoarseToFine => "coarse_to_fine",
            Method::Vmd => "vmd",
            Method::Emd => "emd",
            Method::Wavelet => "wavelet",
        }
    }
}

/// All parameters of a decomposition (JSON `params`; every field optional): the pipeline's
/// plus the grid reading (`order`, `nu`, `nv`) and `full_components`.
pub type DecomposeParams = CoarseToFineParams;

/// Arrays of a full-components answer.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StageArrays {
    /// The VMD modes, mm, one vector per mode.
    pub vmd_modes: Vec<Vec<f64>>,
    /// Stage 1: sum of the strong VMD modes, mm (coarse-to-fine only).
    pub x1: Vec<f64>,
    /// Stage 2: sum of the strong EMD(X1) components, mm (coarse-to-fine only).
    pub x2: Vec<f64>,
    /// Stage 3: wavelet soft-threshold of the weak components, mm (coarse-to-fine only).
    pub x3: Vec<f64>,
    /// Stage 4: X2 + X3, mm (coarse-to-fine only).
    pub x4: Vec<f64>,
}

/// What the stages found, per method.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Components {
    /// The order actually used (`2d`, `serpentine`, `row_major`) when a grid was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub order: Option<Order>,
    /// Grid shape `[nu, nv]` when the signal was a grid.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grid: Option<[usize; 2]>,
    /// What each stage found (method `coarse_to_fine`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stages: Option<CoarseToFineResult>,
    /// Correlation r of each component against the signal (methods `vmd`, `emd`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corr: Option<Vec<f64>>,
    /// Kept mask of the components, |r| ≥ threshold (methods `vmd`, `emd`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub strong: Option<Vec<bool>>,
    /// VMD centre frequencies, cycles/sample (method `vmd`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub omega: Option<Vec<f64>>,
    /// Decomposition level used (method `wavelet`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wavelet_level: Option<usize>,
    /// Noise estimate σ̂, mm (method `wavelet`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// Every stage's arrays, when `full_components` was asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub arrays: Option<StageArrays>,
}

/// A decomposition: systematic + random == signal sample by sample (random is computed as
/// the difference, so the identity holds to rounding, ≤ 1e-15 relative).
#[derive(Clone, Debug, Serialize)]
pub struct Decomposition {
    /// The method that produced it.
    pub method: Method,
    /// Systematic (compensable) part, mm, in the input's sample (or grid) order.
    pub systematic: Vec<f64>,
    /// Random part, mm: signal − systematic.
    pub random: Vec<f64>,
    /// What the stages found.
    pub components: Components,
    /// Probe flyers found (sample or grid indices k, ascending): left out of the systematic
    /// part, which there comes from their neighbours; their whole deviation is in `random`
    /// ([`super::flyers`], openapi.yaml measurement upload and decomposition `outliers`).
    pub outliers: Vec<usize>,
    /// The VMD sweep's kernel that computed it ([`super::vmd::kernel`]: `avx2-fma` or
    /// `portable`), for the methods that run VMD: the same input, version and kernel give
    /// the same bits on any host.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kernel: Option<&'static str>,
}

/// Decompositions in progress in the process ([`decompose`] calls). Each also counts its
/// thread among the process's busy threads (`numeric::parallel::busy`), which the VMD
/// iteration reads to decide whether a second thread would find a free core.
static RUNNING: AtomicUsize = AtomicUsize::new(0);

/// The number of [`decompose`] calls in progress in the process, the caller's included.
#[cfg(test)]
pub(crate) fn decompositions_running() -> usize {
    RUNNING.load(Ordering::Relaxed)
}

/// Counts one [`decompose`] call in [`RUNNING`] while it lives.
struct Running;

impl Running {
    fn enter() -> Self {
        RUNNING.fetch_add(1, Ordering::Relaxed);
        Running
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        RUNNING.fetch_sub(1, Ordering::Relaxed);
    }
}

/// Largest accepted signal (openapi.yaml: sync up to 250,000 samples; the core takes 4x that).
pub const MAX_SAMPLES: usize = 1_000_000;

/// Decomposes `x` (mm) with `method`. With a grid (`params.nu`, `params.nv`, k = iv·nu + iu)
/// the `order` decides how it is read: `2d` runs the 1-D stages on the serpentine order
/// (stage diagnostics) and the refinement smoother on the field itself; the single-method
/// baselines, being 1-D, read `2d` as serpentine.
///
/// Probe flyers (`params.flyers`, on by default) are found and left out first
/// ([`super::flyers`]): on clean data the answer is the plain decomposition, bit for bit.
///
/// Reference: Chen et al. 2024; see [`coarse_to_fine`] for the stages. Known bad cases: see there
/// and [`super::flyers`].
pub fn decompose(
    x: &[f64],
    method: Method,
    params: &DecomposeParams,
) -> Result<Decomposition, Error> {
    let _running = Running::enter();
    // Among the process's busy threads, for the split decisions of other work.
    let _busy = crate::numeric::parallel::busy();
    check_signal(method.as_str(), x, 16)?;
    params.flyers.validate()?;
    let grid = match (params.nu, params.nv) {
        (Some(nu), Some(nv)) if nu.checked_mul(nv) == Some(x.len()) => Some((nu, nv)),
        _ => None,
    };
    let (outliers, mut d) = flyers::robust(
        x,
        grid,
        &params.flyers,
        |y| decompose_plain(y, method, params),
        |d| &d.systematic,
    )?;
    if !outliers.is_empty() {
        // The last run saw the filled signal; the random part is against the measured one.
        d.random = x.iter().zip(&d.systematic).map(|(a, b)| a - b).collect();
    }
    d.outliers = outliers;
    if d.systematic.iter().chain(&d.random).any(|v| !v.is_finite()) {
        let max_abs = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        return Err(Error::Overflow { max_abs });
    }
    Ok(d)
}

/// [`decompose`] without the flyer screen.
fn decompose_plain(
    x: &[f64],
    method: Method,
    params: &DecomposeParams,
) -> Result<Decomposition, Error> {
    check_signal(method.as_str(), x, 16)?;
    if x.len() > MAX_SAMPLES {
        return Err(Error::BadParam {
            name: "signal",
            reason: format!("{} samples exceed the limit of {MAX_SAMPLES}", x.len()),
        });
    }
    params.validate()?;
    let grid = match (params.nu, params.nv) {
        (Some(nu), Some(nv)) => {
            check_grid(x.len(), nu, nv)?;
            Some((nu, nv))
        }
        (None, None) => None,
        _ => {
            return Err(Error::BadParam {
                name: "nu",
                reason: "give both nu and nv (the grid shape) or neither".into(),
            });
        }
    };
    let mut order = grid.map(|_| params.order);
    if let (Some((nu, nv)), Some(Order::TwoD)) = (grid, order) {
        if method != Method::CoarseToFine || !params.refine || nu.max(nv) > MAX_SIDE_2D {
            order = Some(Order::Serpentine);
        }
    }
    let flat = match (grid, order) {
        (Some((nu, nv)), Some(Order::TwoD)) => flatten(x, nu, nv, Order::Serpentine),
        (Some((nu, nv)), Some(o)) => flatten(x, nu, nv, o),
        _ => x.to_vec(),
    };
    let p = params;
    let mut comps = Components {
        order,
        grid: grid.map(|(a, b)| [a, b]),
        ..Default::default()
    };
    let systematic_flat = match method {
        Method::CoarseToFine => {
            let two_d = order == Some(Order::TwoD);
            let d = p.smoothing_order.unwrap_or(if two_d { 3 } else { 4 });
            let mut r = coarse_to_fine(&flat, p, d)?;
            if let (true, Some((nu, nv))) = (two_d, grid) {
                // Refinement on the field: narrow-band modes found along the serpentine
                // path, the rest smoothed in 2-D.
                let lambda = p.lambda;
                let smooth = move |r: &[f64]| -> Result<Smoothed, Error> {
                    let grid = unflatten(r, nu, nv, Order::Serpentine);
                    let s = whittaker_2d(&grid, nu, nv, d, lambda)?;
                    Ok(Smoothed {
                        signal: flatten(&s.signal, nu, nv, Order::Serpentine),
                        ..s
                    })
                };
                let (h, bands, s) =
                    narrow_band_part(&flat, &r.vmd_modes, &r.vmd_strong, None, &smooth)?;
                r.systematic = s.signal.iter().zip(&h).map(|(a, b)| a + b).collect();
                r.refine = Some(s);
                r.narrow_band_modes = bands.iter().map(|b| b.mode).collect();
                r.narrow_band = bands;
            }
            let sys = std::mem::take(&mut r.systematic);
            if params.full_components {
                comps.arrays = Some(StageArrays {
                    vmd_modes: std::mem::take(&mut r.vmd_modes),
                    x1: std::mem::take(&mut r.x1),
                    x2: std::mem::take(&mut r.x2),
                    x3: std::mem::take(&mut r.x3),
                    x4: std::mem::take(&mut r.x4),
                });
            }
            comps.stages = Some(r);
            sys
        }
        Method::Vmd => {
            let k = match p.vmd.k {
                Some(k) => k,
                None => choose_k(&flat, &p.vmd, p.k_max)?,
            };
            let v = vmd(
                &flat,
                &VmdParams {
                    k: Some(k),
                    ..p.vmd.clone()
                },
            )?;
            let (r, strong) = screen(&v.modes, &flat, p.threshold);
            let sys = sum_selected(&v.modes, &strong, flat.len());
            comps.corr = Some(r);
            comps.strong = Some(strong);
            comps.omega = Some(v.omega);
            if params.full_components {
                comps.arrays = Some(StageArrays {
                    vmd_modes: v.modes,
                    ..Default::default()
                });
            }
            sys
        }
        Method::Emd => {
            let e = emd(&flat, &p.emd)?;
            let mut c = e.imfs;
            c.push(e.residue);
            let (r, strong) = screen(&c, &flat, p.threshold);
            let sys = sum_selected(&c, &strong, flat.len());
            comps.corr = Some(r);
            comps.strong = Some(strong);
            sys
        }
        Method::Wavelet => {
            let w = Wavelet::new(&p.wavelet)?;
            let level = p.wavelet_level.resolve(&flat, &w);
            let d = denoise(&flat, &w, Some(level));
            comps.wavelet_level = Some(d.level);
            comps.sigma = Some(d.sigma);
            d.signal
        }
    };
    let systematic = match (grid, order) {
        (Some((nu, nv)), Some(Order::TwoD)) => {
            unflatten(&systematic_flat, nu, nv, Order::Serpentine)
        }
        (Some((nu, nv)), Some(o)) => unflatten(&systematic_flat, nu, nv, o),
        _ => systematic_flat,
    };
    let random = x.iter().zip(&systematic).map(|(a, b)| a - b).collect();
    Ok(Decomposition {
        method,
        systematic,
        random,
        components: comps,
        outliers: Vec::new(),
        kernel: matches!(method, Method::CoarseToFine | Method::Vmd).then(super::vmd::kernel),
    })
}

#[cfg(test)]
mod tests;
